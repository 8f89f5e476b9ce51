"""The open points of the Ideal Aerosmith table language, as settings (``turntable.aerosmith`` in a bench file).

The public sources (the wire-protocol notes in docs/protocols/ideal-aerosmith.md and the public Python package
``aerosmith`` on GitHub, which documents the commands HOM, ACL, CAL, CLU, JOG, REX, SRV, STO) leave these points
open; each is a setting with the default those sources suggest, and the simulated twin answers the same way.
"""

from __future__ import annotations

from dataclasses import dataclass

GIMBALS = ("outer", "middle", "inner")


@dataclass(frozen=True)
class AerosmithSettings:
    """How one Ideal Aerosmith controller talks.

    Attributes
    ----------
    axis : {"outer", "middle", "inner"}
        Which gimbal of the bench's (outer, middle, inner) frame the table's single axis is; the other two are
        absent (their limits are :meth:`drivers.protocols.AxisLimits.absent`).
    command_terminator : str
        Appended to every command. The public package sends none (its default here); a controller set up to
        wait for CR needs ``"\\r"``.
    prompt : str
        What ends every reply: the controller's prompt line. The public package waits for CR LF ``>`` CR LF.
    position_query, rate_query : str
        Readback commands (sent with ``?``): not in the public package — confirm them in your controller's manual.
        Defaults ``POS`` and ``RAT`` (answered in degrees and °/s).
    """

    axis: str = "inner"
    command_terminator: str = ""
    prompt: str = "\r\n>\r\n"
    position_query: str = "POS"
    rate_query: str = "RAT"

    def __post_init__(self) -> None:
        if self.axis not in GIMBALS:
            raise ValueError(f"axis must be one of {', '.join(GIMBALS)}, got {self.axis!r}")
        if not self.prompt:
            raise ValueError("prompt must not be empty (it ends every reply)")

    @property
    def index(self) -> int:
        """The gimbal index (0 outer, 1 middle, 2 inner) of the table's axis."""
        return GIMBALS.index(self.axis)


__all__ = ["GIMBALS", "AerosmithSettings"]

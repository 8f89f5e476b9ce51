"""The open points of the ACUTROL3000 command language, as settings (``turntable.acl`` in a bench file).

The vendor documents (``docs/protocols/acutrol-acl.md``) leave these points open; they are captured from a
real unit and written into the bench file, never guessed in code. Defaults follow the spec.
Both the driver (:mod:`drivers.acutrol.driver`) and the simulated controller
(:mod:`drivers.sim.acl_controller`) read the same settings, so a simulated bench can imitate any real unit.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

ReplyProfile = Literal["gpib", "tcp"]
ModeReply = Literal["letter", "word"]


@dataclass(frozen=True)
class AclSettings:
    """How one ACUTROL3000 answers (the spec's open points).

    Attributes
    ----------
    reply_profile : {"gpib", "tcp"}
        ``gpib``: only queries produce a reply (TM-8004 §2). ``tcp`` (TCP and RS-232, firmware ≥ 1848): a
        message without queries is answered by an empty line; a message with queries by its data line.
    mode_reply : {"letter", "word"}
        ``:Mode? a`` answers ``P`` (manual, §4.7) or ``Position`` (what the public client expects).
    decimals : int
        Output precision: digits after the decimal point in numeric replies (``:Configure:Scaling`` format).
    axes : (int, int, int)
        Controller axis numbers of the outer, middle and inner gimbal.
    full_scale_deg : float
        Position full-scale range: positions wrap at ±full_scale/2 (default 360 → ±180°).
    time_variable : int or None
        System variable number of the controller's time clock, read with ``:Read:Variable? N`` in the same
        message as the positions (one frame); None: the driver time-stamps readings with the host clock.
    time_scale_s : float
        Seconds per unit of the time-clock variable (the ACP time clock counts milliseconds: 0.001).
    error_queue : str
        Queue mnemonic for ``:Status:MSG? <qid>`` when the status byte says the error queue is not empty.
    open_interlocks_at_end : bool
        Send ``:Interlock:Open`` on every axis when the session ends (after ``:Mode:Off``).
    source : str
        Where the reply profile was set (``bench.yaml:17 turntable.acl.reply_profile``), named in the errors a
        reply-profile mismatch causes; not part of the settings' identity.
    """

    reply_profile: ReplyProfile = "tcp"
    mode_reply: ModeReply = "letter"
    decimals: int = 4
    axes: tuple[int, int, int] = (1, 2, 3)
    full_scale_deg: float = 360.0
    time_variable: int | None = None
    time_scale_s: float = 0.001
    error_queue: str = "QERROR"
    open_interlocks_at_end: bool = False
    source: str = field(default="", compare=False)

    @property
    def profile_hint(self) -> str:
        """``check turntable.acl.reply_profile (now 'tcp'; set at …)``: the fix for a reply-profile mismatch."""
        where = f"; set at {self.source}" if self.source else ""
        return (
            f"check turntable.acl.reply_profile (now {self.reply_profile!r}{where}; tcp: an empty line after every "
            "command, gpib: nothing)"
        )

    def __post_init__(self) -> None:
        if self.reply_profile not in ("gpib", "tcp"):
            raise ValueError(f"reply_profile must be 'gpib' or 'tcp', got {self.reply_profile!r}")
        if self.mode_reply not in ("letter", "word"):
            raise ValueError(f"mode_reply must be 'letter' or 'word', got {self.mode_reply!r}")
        if not 0 <= int(self.decimals) <= 12:
            raise ValueError(f"decimals must be 0..12, got {self.decimals!r}")
        if len(self.axes) != 3 or len(set(self.axes)) != 3 or any(int(a) < 1 for a in self.axes):
            raise ValueError(f"axes must be three different controller axis numbers ≥ 1, got {self.axes!r}")
        if not self.full_scale_deg > 0:
            raise ValueError(f"full_scale_deg must be > 0, got {self.full_scale_deg!r}")
        if not self.time_scale_s > 0:
            raise ValueError(f"time_scale_s must be > 0, got {self.time_scale_s!r}")


def default_profile(resource: str) -> ReplyProfile:
    """The reply profile a VISA resource string implies: ``GPIB…`` → gpib, anything else (TCPIP, ASRL) → tcp."""
    return "gpib" if resource.strip().upper().startswith("GPIB") else "tcp"


__all__ = ["AclSettings", "ModeReply", "ReplyProfile", "default_profile"]

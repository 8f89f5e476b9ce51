"""The chamber's readings of a recorded thermal run (``benches/RECORDING.md``, "/aux/chamber").

Runs recorded since the chamber had its own recording group keep its readings under ``/aux/chamber``
(set point, air and unit temperature, K; running and alarm, 0/1). Older recordings have the same readings only
as event-log lines ``chamber: setpoint_K=… air_K=… unit_K=… running=… alarm=…``: :func:`chamber_readings`
reads either, so an old recording stays readable.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

AUX_NAME = "chamber"
_LINE = re.compile(
    r"^chamber: setpoint_K=(?P<setpoint>\S+) air_K=(?P<air>\S+) unit_K=(?P<unit>\S+)"
    r"(?: running=(?P<running>True|False) alarm=(?P<alarm>True|False))?"
)


@dataclass(frozen=True)
class ChamberRecord:
    """The chamber's readings over a run.

    Attributes
    ----------
    time : ndarray (A,)
        Bench time of each reading, s.
    channels : dict
        ``setpoint``, ``air``, ``unit`` (K) and, when recorded, ``running``, ``alarm`` (0/1); NaN where missing.
    source : str
        ``"aux"`` (the recording group) or ``"events"`` (an older recording's event lines).
    """

    time: NDArray[np.float64]
    channels: dict[str, NDArray[np.float64]]
    source: str

    def __len__(self) -> int:
        return int(self.time.size)


def _number(text: str | None) -> float:
    if text is None:
        return float("nan")
    if text in ("True", "False"):
        return float(text == "True")
    try:
        return float(text)
    except ValueError:
        return float("nan")


def chamber_readings(rec: Any) -> ChamberRecord:
    """The chamber's readings of an open recording (:class:`benches.recording.Recording`); empty without any."""
    if AUX_NAME in rec.aux_names():
        a = rec.aux(AUX_NAME)
        return ChamberRecord(np.asarray(a.time, dtype=float), dict(a.channels), "aux")
    rows: list[tuple[float, dict[str, float]]] = []
    for e in rec.events():
        m = _LINE.match(e.message)
        if m is not None:
            rows.append((float(e.time), {k: _number(v) for k, v in m.groupdict().items()}))
    names = ("setpoint", "air", "unit", "running", "alarm")
    time = np.array([t for t, _ in rows], dtype=float)
    channels = {k: np.array([v[k] for _, v in rows], dtype=float) for k in names}
    return ChamberRecord(time, channels, "events" if rows else "none")

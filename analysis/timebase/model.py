"""The time base of a run as a typed result: t_table = t₀ + (1 + ε) · t_unit, with uncertainties.

``t_unit`` is the unit's sample clock (its sample time stamps, s); ``t_table`` the clock the table's readings are
stamped with (the controller's time variable, or the host's clock when an answer arrives). The unit's output
latency is separate: a sample stamped t_unit measures the table at t_unit − latency (unit time), i.e. at table
time t₀ + (1 + ε)(t_unit − latency). See docs/methods/time-base.md.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray


@dataclass(frozen=True)
class TimingEvent:
    """The clock offset seen around one motion of the table.

    Attributes
    ----------
    t_unit : float
        Unit time of the motion (mean of its readings), s.
    offset : float
        Local offset t_table − (1 + ε₀) t_unit found there, s (ε₀ the run's estimated rate).
    u : float
        Its standard uncertainty, s (from the fit's residuals).
    axis : int
        Gimbal axis that moved (0 outer, 1 middle, 2 inner).
    readings : int
        Table readings used.
    rms_time : float
        RMS of the fit's residuals expressed as time (residual / rate of change of the signal), s.
    residual : float
        The event's offset minus the run's fitted line, s (filled by the run fit).
    jitter : float
        Timing jitter within the motion, s: the excess of the fit's residuals while the table moves over those
        at rest (the unit's and the encoder's noise), expressed as time; 0 when the excess is not significant
        (the moving residuals' variance within 3σ of the resting ones').
    """

    t_unit: float
    offset: float
    u: float
    axis: int
    readings: int
    rms_time: float
    residual: float = 0.0
    jitter: float = 0.0


@dataclass(frozen=True)
class TimeBase:
    """Estimated mapping from the unit's sample clock to the table's clock (SI: s, dimensionless rate).

    Attributes
    ----------
    offset : float
        t₀, s: table time at unit time 0.
    rate : float
        ε: the table clock's rate relative to the unit's, minus 1 (1e-6 = 1 ppm).
    u_offset, u_rate : float
        Standard uncertainties (k = 1).
    covariance : (2, 2) ndarray
        Covariance of (t₀, ε).
    method : str
        How it was found: "gyro" (gyro rate against table rate around motions), "accelerometer" (specific-force
        changes around moves), "identity" (nothing to estimate from: one clock assumed), "hardware" (declared
        by the bench: the estimate only checks it).
    events : list of TimingEvent
        The per-motion offsets the fit used.
    misfit : float
        Birge ratio √(χ²/dof) of the events about the fitted line (1: consistent with their σ).
    check : dict
        Independent bounds from the recorded host/controller clocks (rate from host arrival times, …).
    notes : list of str
        Plain-language remarks (skipped motions, misfit causes).
    """

    offset: float = 0.0
    rate: float = 0.0
    u_offset: float = 0.0
    u_rate: float = 0.0
    covariance: NDArray[np.float64] = field(default_factory=lambda: np.zeros((2, 2)))
    method: str = "identity"
    events: list[TimingEvent] = field(default_factory=list)
    misfit: float = 0.0
    check: dict[str, Any] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)

    def to_unit_time(self, t_table: ArrayLike) -> NDArray[np.float64]:
        """Unit time (s) of table time stamps ``t_table`` (s)."""
        return (np.asarray(t_table, dtype=float) - self.offset) / (1.0 + self.rate)

    def to_table_time(self, t_unit: ArrayLike) -> NDArray[np.float64]:
        """Table time (s) of unit time stamps ``t_unit`` (s)."""
        return self.offset + (1.0 + self.rate) * np.asarray(t_unit, dtype=float)

    def shifted(self, d_offset: float = 0.0, d_rate: float = 0.0) -> TimeBase:
        """The same time base with offset and rate moved by ``d_offset`` s and ``d_rate`` (sensitivities)."""
        return TimeBase(self.offset + d_offset, self.rate + d_rate, method=self.method)

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready (SI numbers; calibration.json's ``time_base``)."""
        return {
            "offset_s": float(self.offset),
            "rate": float(self.rate),
            "u_offset_s": float(self.u_offset),
            "u_rate": float(self.u_rate),
            "covariance": [[float(x) for x in row] for row in np.asarray(self.covariance, float)],
            "method": self.method,
            "model": "t_table = offset + (1 + rate) * t_unit",
            "misfit": float(self.misfit),
            "events": [
                {
                    "t_unit_s": e.t_unit,
                    "offset_s": e.offset,
                    "u_s": e.u,
                    "axis": e.axis,
                    "readings": e.readings,
                    "rms_time_s": e.rms_time,
                    "residual_s": e.residual,
                    "jitter_s": e.jitter,
                }
                for e in self.events
            ],
            "check": _finite(self.check),
            "notes": list(self.notes),
        }

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> TimeBase:
        """Inverse of :meth:`as_dict`."""
        cov = np.asarray(d.get("covariance") or np.zeros((2, 2)), dtype=float).reshape(2, 2)
        events = [
            TimingEvent(
                float(e["t_unit_s"]),
                float(e["offset_s"]),
                float(e["u_s"]),
                int(e["axis"]),
                int(e["readings"]),
                float(e["rms_time_s"]),
                float(e.get("residual_s", 0.0)),
                float(e.get("jitter_s", 0.0)),
            )
            for e in d.get("events", [])
        ]
        nan = math.nan
        return cls(
            float(d.get("offset_s", 0.0)),
            float(d.get("rate", 0.0)),
            float(d.get("u_offset_s", nan)),
            float(d.get("u_rate", nan)),
            cov,
            str(d.get("method", "")),
            events,
            float(d.get("misfit", 0.0)),
            dict(d.get("check") or {}),
            list(d.get("notes") or []),
        )

    def summary(self) -> str:
        """One line: offset and rate with u (k = 1), and the method."""
        return (
            f"time base ({self.method}): offset {self.offset * 1e3:.4f} ± {self.u_offset * 1e3:.4f} ms, "
            f"rate {self.rate * 1e6:+.3f} ± {self.u_rate * 1e6:.3f} ppm (u, k = 1; t_table = offset + (1 + rate) "
            f"t_unit; {len(self.events)} motions, misfit {self.misfit:.2f})"
        )


def _finite(d: dict[str, Any]) -> dict[str, Any]:
    """A JSON-safe copy: non-finite floats become None."""
    out: dict[str, Any] = {}
    for k, v in d.items():
        if isinstance(v, float) and not math.isfinite(v):
            out[k] = None
        elif isinstance(v, dict):
            out[k] = _finite(v)
        else:
            out[k] = v
    return out


IDENTITY = TimeBase()
"""One clock: t_table = t_unit (no uncertainty claimed)."""

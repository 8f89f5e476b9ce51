"""The soak criterion: when is the unit settled at a temperature plateau? (docs/methods/thermal.md)

Settled when, for a continuous ``dwell``, the unit's own temperature T_u is within ``tolerance`` of the
target (set point + expected self-heating) and its rate |Ṫ_u| is below ``rate_limit``. The rate is the slope
of a straight line fitted to the last ``rate_window`` seconds of 1-second means of the unit's temperature
channel (a difference of two quantised samples would be all noise). Typical values (0.5 K, 0.1 K/min, 10 min)
are procedure parameters, not a standard (thermal-chamber practice; Niu et al. 2013 soak at each plateau).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from analysis.units import kelvin_to_celsius


@dataclass(frozen=True)
class SoakCriterion:
    """Parameters of a soak, SI.

    Attributes
    ----------
    tolerance : float
        δ: largest |T_u − target|, K.
    rate_limit : float
        Largest |Ṫ_u|, K/s.
    dwell : float
        Time both must hold without a break, s.
    timeout : float
        Longest soak, s (the step fails after it).
    rate_window : float
        Span of the rate fit, s.
    """

    tolerance: float = 0.5
    rate_limit: float = 0.1 / 60.0
    dwell: float = 600.0
    timeout: float = 4 * 3600.0
    rate_window: float = 120.0

    def __post_init__(self) -> None:
        for name in ("tolerance", "rate_limit", "timeout", "rate_window"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise ValueError(f"soak {name} must be > 0, got {v!r}")
        if not (math.isfinite(self.dwell) and self.dwell >= 0):
            raise ValueError(f"soak dwell must be >= 0 s, got {self.dwell!r}")


class SoakMonitor:
    """Feed the unit's temperature as it arrives; ask :attr:`settled`.

    Parameters
    ----------
    criterion : SoakCriterion
    target : float
        Temperature the unit must reach, K (set point + expected self-heating).
    start : float
        Bench time the soak starts, s.
    """

    def __init__(self, criterion: SoakCriterion, target: float, start: float) -> None:
        self.c = criterion
        self.target = float(target)
        self.start = float(start)
        self._sec: list[tuple[float, float]] = []  # (second start, mean T) of completed seconds
        self._acc_t: float | None = None
        self._acc: list[float] = []
        self._ok_since: float | None = None
        self.settled_at: float | None = None
        self.last_temperature = math.nan
        self.last_rate = math.nan
        self.now = self.start

    def feed(self, time: ArrayLike, temperature: ArrayLike) -> bool:
        """Add samples (bench time s, unit temperature K); return :attr:`settled`."""
        t = np.asarray(time, dtype=float).reshape(-1)
        x = np.asarray(temperature, dtype=float).reshape(-1)
        good = np.isfinite(t) & np.isfinite(x)
        t, x = t[good], x[good]
        if t.size == 0:
            return self.settled
        sec = np.floor(t)
        edges = np.flatnonzero(np.diff(sec)) + 1
        for part_t, part_x in zip(np.split(sec, edges), np.split(x, edges), strict=True):
            s = float(part_t[0])
            if self._acc_t is not None and s != self._acc_t:
                self._close_second()
            self._acc_t = s
            self._acc.extend(part_x.tolist())
        self.now = float(t[-1])
        return self.settled

    def _close_second(self) -> None:
        assert self._acc_t is not None
        self._sec.append((self._acc_t + 0.5, float(np.mean(self._acc))))
        self._acc = []
        cut = self._sec[-1][0] - self.c.rate_window
        while self._sec and self._sec[0][0] < cut:
            self._sec.pop(0)
        self._check(self._sec[-1][0])

    def _check(self, now: float) -> None:
        if self.settled_at is not None:
            return
        ts = np.array([s[0] for s in self._sec])
        xs = np.array([s[1] for s in self._sec])
        self.last_temperature = float(xs[-1])
        if ts[-1] - ts[0] < 0.5 * self.c.rate_window or ts.size < 3:
            self._ok_since = None
            return
        self.last_rate = float(np.polyfit(ts - ts[-1], xs, 1)[0])
        ok = abs(xs[-1] - self.target) <= self.c.tolerance and abs(self.last_rate) <= self.c.rate_limit
        if not ok:
            self._ok_since = None
            return
        if self._ok_since is None:
            self._ok_since = now
        if now - self._ok_since >= self.c.dwell:
            self.settled_at = now

    @property
    def settled(self) -> bool:
        """True once the criterion has held for the dwell."""
        return self.settled_at is not None

    @property
    def timed_out(self) -> bool:
        """True if the soak ran past its time-out without settling."""
        return not self.settled and self.now - self.start > self.c.timeout

    def status(self) -> str:
        """One line for the progress display."""
        rate = "?" if math.isnan(self.last_rate) else f"{self.last_rate * 60:+.3f} K/min"
        return (
            f"unit {kelvin_to_celsius(self.last_temperature):.2f} °C (target {kelvin_to_celsius(self.target):.2f} °C), "
            f"rate {rate}, "
            f"{self.now - self.start:.0f} s into the soak"
        )

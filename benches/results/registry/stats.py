"""The statistics of a unit's history: E_n, control limits, repeatability and reproducibility, intervals.

* **Normalised error** (ISO/IEC 17043 B.4, EA-4/02): E_n = |x₂ − x₁| / √(U₁² + U₂²), U the expanded
  uncertainties (k = 2); |E_n| ≤ 1: the two results agree within their uncertainties.
* **Control limits** (ISO 7870-2, individuals chart): centre x̄ of the unit's values, σ̂ = MR̄ / d₂ with MR̄ the
  mean moving range of consecutive values and d₂ = 1.128; warning limits x̄ ± 2σ̂, action limits x̄ ± 3σ̂.
* **Repeatability and reproducibility** (ISO 5725-2 §7.4, unbalanced): per bench i with nᵢ calibrations of
  the unit, mean ȳᵢ and variance sᵢ²; s_r² = Σ(nᵢ − 1)sᵢ² / Σ(nᵢ − 1); s_d² = Σnᵢ(ȳᵢ − ȳ)² / (p − 1);
  n̄ = (Σnᵢ − Σnᵢ²/Σnᵢ) / (p − 1); s_L² = max(0, (s_d² − s_r²) / n̄); s_R² = s_L² + s_r².
* **Recalibration intervals** (ILAC-G24:2022 / OIML D 10): method 1 "staircase" — after each calibration
  the interval is multiplied by ``extend`` when the unit was found in tolerance (every identified parameter
  agrees with the previous calibration, E_n ≤ 1, and the decision was not FAIL), by ``reduce`` otherwise,
  kept within [min, max]; method 2 "control chart" — per identified parameter the drift rate (least-squares
  slope of value against time) and the scatter about it (s); the interval is the time for the drift to use
  up the allowance (``drift_allowance_U`` × the last U, less 2 s), the shortest over the parameters, kept
  within [min, max]. Settings: the bench file's ``recalibration`` section (``docs/registry.md``).
"""

from __future__ import annotations

import datetime as _dt
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from benches.results.recalibration import IntervalSettings

D2 = 1.128
"""d₂ of a moving range of two (ISO 7870-2 Table 2)."""


def normalised_error(x1: float, u1_expanded: float, x2: float, u2_expanded: float) -> float:
    """E_n = |x₂ − x₁| / √(U₁² + U₂²) (k = 2 expanded uncertainties); inf when both U are 0 and x differ."""
    den = math.hypot(u1_expanded, u2_expanded)
    d = abs(x2 - x1)
    if den == 0.0:
        return 0.0 if d == 0.0 else math.inf
    return d / den


@dataclass(frozen=True)
class ControlLimits:
    """Individuals chart of one parameter (SI): centre, σ̂ from the moving range, 2σ̂ and 3σ̂ limits."""

    centre: float
    sigma: float
    warning: tuple[float, float]
    action: tuple[float, float]
    points: int


def control_limits(values: Sequence[float]) -> ControlLimits | None:
    """Limits from a unit's own history (None with fewer than 3 values: a moving range needs history)."""
    x = np.asarray(values, dtype=float)
    if x.size < 3:
        return None
    mr = np.abs(np.diff(x))
    sigma = float(np.mean(mr) / D2)
    c = float(np.mean(x))
    return ControlLimits(c, sigma, (c - 2 * sigma, c + 2 * sigma), (c - 3 * sigma, c + 3 * sigma), int(x.size))


@dataclass(frozen=True)
class Precision:
    """ISO 5725-2 precision of one parameter: s_r (repeatability), s_L (between benches), s_R (reproducibility).

    ``benches`` is the number of benches p; ``dof_r`` = Σ(nᵢ − 1). s_R and s_L are None with one bench.
    """

    s_r: float | None
    s_L: float | None  # noqa: N815 - ISO 5725 symbol
    s_R: float | None  # noqa: N815 - ISO 5725 symbol
    benches: int
    calibrations: int
    dof_r: int


def precision(groups: Sequence[Sequence[float]]) -> Precision:
    """s_r, s_L, s_R from a unit's values grouped by bench (see the module docstring)."""
    gs = [np.asarray(g, dtype=float) for g in groups if len(g) > 0]
    n = np.array([g.size for g in gs])
    total = int(n.sum()) if n.size else 0
    dof_r = int(np.sum(n - 1)) if n.size else 0
    s_r2 = float(sum(np.var(g, ddof=1) * (g.size - 1) for g in gs if g.size > 1) / dof_r) if dof_r > 0 else None
    p = len(gs)
    if p < 2 or s_r2 is None:
        return Precision(None if s_r2 is None else math.sqrt(s_r2), None, None, p, total, dof_r)
    means = np.array([g.mean() for g in gs])
    grand = float(np.sum(n * means) / total)
    s_d2 = float(np.sum(n * (means - grand) ** 2) / (p - 1))
    n_bar = float((total - np.sum(n**2) / total) / (p - 1))
    s_l2 = max(0.0, (s_d2 - s_r2) / n_bar)
    return Precision(math.sqrt(s_r2), math.sqrt(s_l2), math.sqrt(s_l2 + s_r2), p, total, dof_r)


def parse_time(text: str) -> _dt.datetime:
    """UTC ISO-8601 text (``2026-11-27T18:00:00Z`` or with fractions/offset) → aware datetime."""
    t = text.strip().replace("Z", "+00:00")
    d = _dt.datetime.fromisoformat(t)
    return d if d.tzinfo is not None else d.replace(tzinfo=_dt.timezone.utc)


def in_tolerance(
    prev_x: NDArray[np.float64], prev_U: NDArray[np.float64], x: NDArray[np.float64], U: NDArray[np.float64],  # noqa: N803
    identified: NDArray[np.bool_], decision: str | None,
) -> bool:  # fmt: skip
    """Found in tolerance: no FAIL decision and E_n ≤ 1 for every parameter identified in both."""
    if decision == "FAIL":
        return False
    en = [normalised_error(prev_x[i], prev_U[i], x[i], U[i]) for i in range(len(x)) if identified[i]]
    return all(e <= 1.0 for e in en)


def staircase(tolerances: Sequence[bool], s: IntervalSettings) -> float:
    """ILAC-G24 method 1: the interval (days) after a history of in/out-of-tolerance findings (oldest first;
    the first calibration has no finding and starts at ``initial_days``)."""
    interval = s.initial_days
    for ok in tolerances:
        interval = interval * (s.extend if ok else s.reduce)
        interval = min(max(interval, s.min_days), s.max_days)
    return interval


@dataclass(frozen=True)
class DriftInterval:
    """ILAC-G24 method 2 for one parameter: drift rate (SI per day), scatter s, allowance, interval (days)."""

    name: str
    rate_per_day: float
    scatter: float
    allowance: float
    interval_days: float


def control_chart_interval(
    name: str, days: Sequence[float], values: Sequence[float], last_U: float, s: IntervalSettings  # noqa: N803
) -> DriftInterval | None:
    """Method 2 for one parameter (None with fewer than 3 calibrations or no time span)."""
    t = np.asarray(days, dtype=float)
    y = np.asarray(values, dtype=float)
    if t.size < 3 or np.ptp(t) <= 0:
        return None
    a = np.vstack([t - t.mean(), np.ones_like(t)]).T
    coef, *_ = np.linalg.lstsq(a, y, rcond=None)
    resid = y - a @ coef
    scatter = float(np.sqrt(np.sum(resid**2) / max(t.size - 2, 1)))
    allowance = s.drift_allowance_U * last_U
    usable = allowance - 2.0 * scatter
    rate = abs(float(coef[0]))
    if usable <= 0:
        interval = s.min_days
    elif rate == 0.0:
        interval = s.max_days
    else:
        interval = min(max(usable / rate, s.min_days), s.max_days)
    return DriftInterval(name, float(coef[0]), scatter, allowance, float(interval))


__all__ = [
    "D2",
    "ControlLimits",
    "DriftInterval",
    "IntervalSettings",
    "Precision",
    "control_chart_interval",
    "control_limits",
    "in_tolerance",
    "normalised_error",
    "parse_time",
    "precision",
    "staircase",
]

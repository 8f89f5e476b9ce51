"""Thermal identification of a recorded run: one calibration per plateau, then the temperature model
(docs/methods/thermal.md).

The recording of a thermal procedure is cut into plateaus at its soak steps: each completed soak opens a
plateau, and the hold and spin windows after it (until the next soak) are that plateau's calibration
sequence. Windows inside a ramp (after a ``ramp-start`` step) form one segment per repetition of the ramp's
sequence, with its own temperature and dT/dt. Each plateau or segment is identified by
:func:`benches.thermal.plateau.identify_plateau` (18 accelerometer + 12 gyro parameters with covariance)
from the same windows and references as the ordinary identification (:func:`benches.identify.load_run`: time
base, latency, flagged samples left out); its temperature is the mean of the unit's temperature channel over
its windows, its rate the slope. The plateau estimates are then fitted by
:func:`analysis.thermal.model.fit_thermal_model` (orders by BIC).

The per-sample noise is the bench's configured white noise (VRW² × rate, ARW² × rate) plus the output
quantisation (LSB²/12). The bench's bias instability (``unit.noise``) is added to each plateau's bias
variances: the bias wanders by about that much within a sequence, which white noise alone does not cover
(the same per-step term as the single-temperature budget, ``benches.identify.bias_stability``).

The gyro scale factors' rate reference is the encoder angle over the unit's time rescaled by the run's time
base (1 + ε), and the reference second itself has an uncertainty: both are common to every plateau of the
run, so they are not in the plateaus' (independent) covariances. They shift every plateau's gyro scale
factors by the same δ = −δε, i.e. only the constant coefficients c_0 of gS_x, gS_y, gS_z, fully correlated:
added to the model's covariance after the fit (:func:`analysis.thermal.model.with_common_offset`), as the
single-temperature identification adds them to its gyro scale factors.
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from analysis.thermal.model import PlateauEstimate, ThermalModel, fit_thermal_model, with_common_offset
from analysis.units import CELSIUS_ZERO
from benches.identify import (
    ACCEL_INVALID,
    GYRO_INVALID,
    IdentificationError,
    _opened,
    bias_stability,
    configured_noise_variance,
    load_run,
    unit_model,
)
from benches.recorded_run import RecordedRun
from benches.thermal.plateau import THERMAL_PARAM_NAMES, PlateauData, identify_plateau
from benches.timebase import reference_rate_covariance

_REPEAT = re.compile(r"~(\d+)$")


@dataclass
class PlateauResult:
    """One plateau (or ramp segment) of a thermal run."""

    name: str
    estimate: PlateauEstimate
    setpoint: float
    """The soak's set point, K (NaN for a ramp segment)."""
    windows: int
    samples: int


@dataclass
class ThermalCalibration:
    """The thermal identification of a run: the plateau estimates and the fitted model (SI)."""

    run: str
    plateaus: list[PlateauResult]
    model: ThermalModel
    names: tuple[str, ...] = THERMAL_PARAM_NAMES
    skipped: list[str] = field(default_factory=list)
    """Plateaus or segments left out, each with its reason."""
    incomplete_steps: list[str] = field(default_factory=list)

    @property
    def estimates(self) -> list[PlateauEstimate]:
        """The plateau estimates, in run order."""
        return [p.estimate for p in self.plateaus]


def _plateau_of_steps(rr: RecordedRun) -> tuple[dict[str, str], dict[str, float], dict[str, int]]:
    """(window step name → plateau name, plateau → set point K, plateau → its soak's start sample)."""
    setpoints: dict[str, float] = {}
    compiled = rr.compiled
    if compiled is not None:
        for s in compiled.steps:
            if s.kind == "soak":
                setpoints[s.name] = float(getattr(s, "setpoint", math.nan))
    of: dict[str, str] = {}
    starts: dict[str, int] = {}
    current: str | None = None
    ramp: str | None = None
    for s in sorted(rr.steps, key=lambda r: r.index):
        if s.kind == "soak" and s.status == "complete":
            current, ramp = s.name, None
            starts[current] = int(s.start_sample)
        elif s.kind == "ramp":
            ramp = s.name
        elif s.kind in ("hold", "spin") and current is not None:
            m = _REPEAT.search(s.name)
            of[s.name] = f"{ramp} #{m.group(1)}" if ramp is not None and m else current
    return of, setpoints, starts


GYRO_SCALES = ("gS_x", "gS_y", "gS_z")


def time_base_scale_covariance(tb: Any) -> NDArray[np.float64]:
    """(3, 3) covariance common to the three gyro scale factors of every plateau from the run's time base:
    u²(ε) (δS_g = −δε) plus the reference second's u² (:func:`benches.timebase.reference_rate_covariance`)."""
    cov = np.asarray(getattr(tb, "covariance", np.zeros((2, 2))), dtype=float)
    var_eps = float(cov[1, 1]) if cov.shape == (2, 2) and np.isfinite(cov[1, 1]) else 0.0
    ref = reference_rate_covariance([f"gyro_S_{a}" for a in "xyz"], tb.check if isinstance(tb.check, dict) else {})
    return np.full((3, 3), var_eps) + ref


def _variances(config: Any) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    var = configured_noise_variance(config, unit_model(config, True))
    scale = getattr(config.unit, "scale", None)
    a_lsb = float(getattr(scale, "accel_lsb", 0.0) or 0.0)
    g_lsb = float(getattr(scale, "gyro_lsb", 0.0) or 0.0)
    return var[:3] + a_lsb**2 / 12.0, var[3:6] + g_lsb**2 / 12.0


def _window_temperature(rec: Any, s: Any, n: int) -> NDArray[np.float64]:
    """The unit's temperature (K) over a window's valid samples (the rows :func:`benches.identify._read_window`
    keeps)."""
    smp = rec.samples(s.acq_start, s.acq_end, ("temperature", "status"))
    valid = (smp.status & (ACCEL_INVALID | GYRO_INVALID)) == 0
    temp = np.asarray(smp.temperature, dtype=float)[valid]
    if temp.size != n:
        raise IdentificationError(f"step {s.name}: {temp.size} temperature samples for {n} unit samples")
    return temp


def identify_thermal(
    run: str | Path | RecordedRun,
    *,
    reference: float | None = None,
    max_order: int = 3,
    rate_term: bool = False,
    time_base: str = "estimate",
    progress: Callable[[str], None] | None = None,
) -> ThermalCalibration:
    """Identify every plateau of a recorded thermal run and fit the temperature model.

    Parameters
    ----------
    run : path or RecordedRun
        Run folder, recording, or an open recorded run (left open).
    reference : float or None
        T_ref of the model, K (None: the mean plateau temperature rounded to a whole °C).
    max_order : int
        Highest polynomial order tried by BIC.
    rate_term : bool
        Fit a dT/dt coefficient too (needs ramp segments at different rates).
    time_base : {"estimate", "none"}
        As for :func:`benches.identify.load_run`.
    """
    with _opened(run) as rr:
        data = load_run(rr, time_base=time_base, with_gyro=True)
        of, setpoints, starts = _plateau_of_steps(rr)
        if not starts:
            raise IdentificationError(
                f"{rr.path}: no completed soak step: not a thermal run (run a thermal procedure such as "
                "procedures/thermal-plateaus.yaml, or identify it with 'tablebench identify')"
            )
        rec = rr.recording
        by_name = {s.name: s for s in rr.steps}
        groups: dict[str, PlateauData] = {}
        for w in data.windows:
            plateau = of.get(w.name)
            if plateau is None or w.gyro is None or w.earth is None:
                continue
            d = groups.setdefault(plateau, PlateauData())
            d.accel.append(w.f_out)
            d.gyro.append(w.gyro)
            d.f_ref.append(w.f_ref)
            d.omega.append(w.omega)
            d.earth.append(w.earth)
            d.temperature.append(_window_temperature(rec, by_name[w.name], len(w.t)))
            d.time.append(w.t)
        acc_var, gyr_var = _variances(data.config)
        b_var = np.square(bias_stability(data.config, unit_model(data.config, True)))  # accel 3, gyro 3
        bias_idx = [THERMAL_PARAM_NAMES.index(n) for n in ("b_x", "b_y", "b_z", "gb_x", "gb_y", "gb_z")]
        results: list[PlateauResult] = []
        skipped: list[str] = []
        for name, d in groups.items():
            try:
                x, cov, temp, rate = identify_plateau(d, acc_var, gyr_var)
            except (ValueError, np.linalg.LinAlgError) as exc:
                skipped.append(f"{name}: {exc}")
                continue
            cov[bias_idx, bias_idx] += b_var
            sp = setpoints.get(name, math.nan)
            direction = ""
            if name in starts:
                t0 = rec.samples(starts[name], starts[name] + 1, ("temperature",)).temperature
                if t0 is not None and len(t0) and math.isfinite(float(t0[0])) and math.isfinite(sp):
                    direction = "heating" if sp > float(t0[0]) else "cooling"
            elif rate:
                direction = "heating" if rate > 0 else "cooling"
            n = int(sum(len(t) for t in d.time))
            results.append(PlateauResult(name, PlateauEstimate(temp, x, cov, rate, direction), sp, len(d.time), n))
            if progress is not None:
                progress(f"{name}: unit {temp - CELSIUS_ZERO:.2f} °C, {len(d.time)} windows, {n} samples")
        temps = [r.estimate.temperature for r in results]
        if len(results) < 2 or np.ptp(temps) <= 0:
            why = "; ".join(skipped) or "complete the run (tablebench run --resume)"
            raise IdentificationError(
                f"{rr.path}: {len(results)} identified plateau(s) at distinct temperatures; a thermal model needs "
                f"at least 2 ({why})"
            )
        ref = float(np.round(np.mean(temps) - CELSIUS_ZERO) + CELSIUS_ZERO) if reference is None else reference
        try:
            model = fit_thermal_model(
                [r.estimate for r in results], THERMAL_PARAM_NAMES, reference=ref, max_order=max_order,
                rate_term=rate_term,
            )  # fmt: skip
        except ValueError as exc:
            raise IdentificationError(f"{rr.path}: thermal model: {exc}") from None
        model = with_common_offset(model, GYRO_SCALES, time_base_scale_covariance(data.time_base))
        return ThermalCalibration(
            str(rr.path), results, model, skipped=skipped, incomplete_steps=list(data.incomplete_steps)
        )


def window_samples(
    run: str | Path | RecordedRun,
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """(f_out (n, 3), ω_out (n, 3), unit temperature K (n,), bench time s (n,)) of a recording's hold and spin
    windows (flagged samples left out, as in the identification)."""
    with _opened(run) as rr:
        data = load_run(rr, time_base="none", with_gyro=True)
        by_name = {s.name: s for s in rr.steps}
        f, g, temp, t = [], [], [], []
        for w in data.windows:
            if w.gyro is None:
                raise IdentificationError(f"{rr.path}: the recording has no gyro data; a thermal correction needs it")
            f.append(w.f_out)
            g.append(w.gyro)
            temp.append(_window_temperature(rr.recording, by_name[w.name], len(w.t)))
            t.append(w.t)
    return np.concatenate(f), np.concatenate(g), np.concatenate(temp), np.concatenate(t)

"""Identification of the accelerometer model from a run: live during the run, and offline from a recording.

This module joins the pure maths of :mod:`analysis.identification.kalman`, :mod:`analysis.identification.batch`
and :mod:`analysis.identification.plan` to the bench: the prior P0 and the white noise R come from the
bench file (or R from the warm-up record), the reference specific force and body rate from the table's own
readings (:mod:`benches.reference`), and the samples from the acquisition windows of complete hold and spin
steps (moves and settling excluded; the warm-up is used only to estimate R when asked).

Uncertainty reported (``u``): the identification's combined standard uncertainty — the filter's covariance
(white noise, ``u_white``) plus the unit's bias instability as correlated flicker between the steps'
acquisition windows (:mod:`analysis.identification.bias_drift`), propagated through the estimator exactly as
the plan does. The live display shows the filter's white-noise 1σ. Results: :class:`CalibrationResult`
(``calibration.json``, ``benches/CALIBRATION_FORMAT.md``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from analysis.identification.batch import batch_identify, information_rank, unobservable_parameters
from analysis.identification.bias_drift import flicker_components, window_mean_covariance
from analysis.identification.kalman import StreamingIdentifier, estimate_measurement_noise
from analysis.identification.model import PARAM_KINDS, PARAM_NAMES, predict
from analysis.identification.plan import IdentificationPlan, PlanStep, plan_identification
from analysis.timebase import IDENTITY, TimeBase, misfit_cause
from analysis.units import DISPLAY_UNITS
from core.errors import UserError
from core.provenance import file_sha256
from drivers.protocols import ImuBlock, TableState
from procedures.steps import CompiledProcedure, Hold, Spin, Step, Warmup
from procedures.trajectory import nominal_samples

from .bench_config import BenchConfig, load_bench_text
from .calibration_result import CalibrationResult
from .progress import ProgressDisplay
from .recording import RecordingError, StepRecord, open_recording
from .reference import reference_at, reference_for_samples
from .timebase import run_time_base, table_in_unit_time, time_base_sensitivity

MODEL_TEXT = (
    "f_out = f + (S + T) f + b + D (f∘f) + diag(r) c(ω), body frame; c(ω) = [ω_y²+ω_z², ω_z²+ω_x², ω_x²+ω_y²]; "
    "misalignment convention δf_i += τ_ij f_j"
)
IDENTIFIED_STEPS: tuple[type[Step], ...] = (Hold, Spin)
"""Steps whose counted samples the identification fits (a warm-up's only estimate the noise)."""
_IDENTIFIED_KINDS = frozenset(t.kind for t in IDENTIFIED_STEPS)  # as written in a recording's steps table
_SI_UNITS = {"bias": "m/s^2", "scale": "1", "misalignment": "rad", "quadratic": "s^2/m", "size_effect": "m"}


class IdentificationError(UserError, RuntimeError):
    """The recording cannot be identified; the message says why and what to do."""


# ---- bench → prior and noise ------------------------------------------------------------------------------------


def prior_covariance(config: BenchConfig) -> NDArray[np.float64]:
    """P0 = diag(σ²) from the bench's ``unit.prior`` (datasheet 1σ per parameter, SI)."""
    prior = config.unit.prior
    missing = [n for n in PARAM_NAMES if n not in prior]
    if missing:
        raise IdentificationError(
            f"bench {config.name!r}: unit prior lacks {', '.join(missing)}; give a datasheet 1σ for all 18 parameters"
        )
    return np.diag([float(prior[n]) ** 2 for n in PARAM_NAMES])


def configured_noise_variance(config: BenchConfig) -> NDArray[np.float64]:
    """Per-sample white-noise variance per axis, (m/s²)²: VRW density² × sample rate (bench file)."""
    return np.asarray(config.unit.noise.vrw, dtype=float) ** 2 * float(config.unit.sample_rate)


def unit_latency(config: BenchConfig) -> float:
    """The unit's output latency (group delay of its anti-alias filter), s, from the bench file (0 if absent).

    The sample stamped t measures the specific force of about t − latency, so the table reference is
    evaluated there; during a spin at ω an unaccounted latency δ turns the reference by ω·δ.
    """
    return float(getattr(config.unit, "latency", 0.0) or 0.0)


def bias_stability(config: BenchConfig) -> NDArray[np.float64]:
    """Bias instability per axis, m/s² (the per-step unmodelled DC offset of the error budget)."""
    return np.asarray(config.unit.noise.bias_instability, dtype=float)


def offset_covariance(windows: list[tuple[float, float]], b: NDArray[np.float64]) -> NDArray[np.float64]:
    """(3, K, K) covariance of the step-mean bias offsets over K acquisition windows (bench s), per body axis.

    The unit's bias instability B (bench file) as flicker noise (:mod:`analysis.identification.bias_drift`): correlated
    between steps, so slow wander across a sequence of positions is propagated, not assumed independent.
    """
    starts = np.array([w[0] for w in windows])
    ends = np.array([w[1] for w in windows])
    out = np.zeros((3, len(windows), len(windows)))
    for axis in range(3):
        if b[axis] > 0:
            out[axis] = window_mean_covariance(starts, ends, *flicker_components(float(b[axis])))
    return out


# ---- the pre-run plan ------------------------------------------------------------------------------------------------


def _plan_steps_and_windows(
    compiled: CompiledProcedure, config: BenchConfig, sample_rate: float | None = None
) -> list[tuple[PlanStep, tuple[float, float]]]:
    rate = float(sample_rate or config.unit.sample_rate)
    limits = config.turntable.limits
    # nominal acquisition window of every step in bench time (step end minus the spin's ramp down)
    ends = np.cumsum(compiled.step_times(limits))
    window: dict[str, tuple[float, float]] = {}
    for step, end in zip(compiled.steps, ends, strict=True):
        if isinstance(step, Spin):
            end = end - step.ramp_time(limits)
        window[step.name] = (float(end - step.duration), float(end))
    out: list[tuple[PlanStep, tuple[float, float]]] = []
    for ns in nominal_samples(compiled, rate, limits=limits):
        if not isinstance(ns.step, IDENTIFIED_STEPS) or not np.all(np.isfinite(ns.angles)):
            continue
        f_ref, omega = reference_at(ns.angles, ns.rates, config.site.g, config.unit.mounting)
        out.append((PlanStep(ns.step.name, f_ref, omega, ns.weights, ns.angles), window[ns.step.name]))
    if not out:
        raise IdentificationError(f"procedure {compiled.name!r} has no hold or spin to identify from")
    return out


def plan_for(compiled: CompiledProcedure, config: BenchConfig) -> IdentificationPlan:
    """Predicted 1σ of every parameter for a procedure on a bench, before any motion.

    White noise from the bench's VRW, prior from its datasheet bounds, and the bias instability as
    correlated flicker between the steps' nominal acquisition windows (:func:`offset_covariance`).
    """
    pairs = _plan_steps_and_windows(compiled, config)
    b = bias_stability(config)
    return plan_identification(
        [p for p, _ in pairs],
        configured_noise_variance(config),
        prior_covariance(config),
        b,
        offset_covariance=offset_covariance([w for _, w in pairs], b),
    )


def acquisition_span(t_first: float, t_last: float, latency: float, sample_rate: float) -> tuple[float, float]:
    """Bench-time span (s) of the table readings that belong to an acquisition window's own motion state.

    From 1.5 sample periods before the first sample's reference time (t_first − latency) to 1.5 sample
    periods after the last sample: the reading the runner takes with each block is stamped at the next
    sample, so it closes the window (the half period covers the unit's time-stamp jitter); a reading later
    than that may already belong to the next motion and is never used
    (:func:`benches.reference.interpolate_table` extrapolates with the reported rate instead).
    """
    dt = 1.5 / sample_rate
    return (t_first - latency - dt, t_last + dt)


# ---- live identification during the run ---------------------------------------------------------------------------


class LiveIdentifier:
    """Runner observer feeding the streaming Kalman filter as the run goes.

    Samples of the acquisition windows are buffered and fused every ``update_seconds`` of data and at each
    step end (one exact information-form update per batch: with Q = 0 grouping samples changes nothing).
    The reference for the buffered samples interpolates the table readings taken during (and just before)
    the buffer at the sample times less the unit's latency — the same readings offline identification
    interpolates. The live filter cannot know the run's time base before its motions are over, so it takes
    the table's and the unit's clocks as one: it equals offline identification with ``time_base="none"``;
    the result written (calibration.json) maps the clocks with the estimated time base.
    """

    def __init__(
        self,
        config: BenchConfig,
        progress: ProgressDisplay | None = None,
        show: tuple[str, ...] = ("b_z", "S_z", "r_x"),
        update_seconds: float = 2.0,
    ) -> None:
        self.config = config
        self.filter = StreamingIdentifier(
            configured_noise_variance(config), prior_covariance(config), sample_rate=config.unit.sample_rate
        )
        self.latency = unit_latency(config)
        self.progress = progress
        self.show = show
        self._flush_n = max(1, int(update_seconds * config.unit.sample_rate))
        self._readings: list[TableState] = []
        self._times: list[NDArray[np.float64]] = []
        self._accel: list[NDArray[np.float64]] = []
        self._n = 0
        self._step: str | None = None
        self._acq_t0 = 0.0

    def on_block(self, step: Step, block: ImuBlock, table: TableState, counts: bool) -> None:
        """Buffer the block if it is inside a hold/spin acquisition window; fuse when enough is buffered."""
        self._readings.append(table)
        if not counts or not isinstance(step, IDENTIFIED_STEPS) or len(block) == 0:
            if self._n == 0:
                del self._readings[:-3]
            return
        if self._step is not None and self._step != step.name:
            self.flush()
        if self._step != step.name:
            self._acq_t0 = float(block.time[0])
        self._step = step.name
        self._times.append(block.time)
        self._accel.append(block.accel)
        self._n += len(block)
        if self._n >= self._flush_n:
            self.flush()

    def on_step_end(self, step: Step, record: StepRecord) -> None:
        """Fuse what is buffered for the step."""
        self.flush()

    def flush(self) -> None:
        """Fuse the buffered samples in one exact filter update and refresh the live display."""
        if self._n == 0 or self._step is None:
            return
        t = np.concatenate(self._times)
        rd = self._readings
        f_ref, omega, _ang = reference_for_samples(
            t,
            np.array([r.time for r in rd]),
            np.stack([r.angles for r in rd]),
            np.stack([r.rates for r in rd]),
            g=self.config.site.g,
            mounting=self.config.unit.mounting,
            latency=self.latency,
            span=acquisition_span(self._acq_t0, float(t[-1]), self.latency, float(self.config.unit.sample_rate)),
        )
        self.filter.update(np.concatenate(self._accel), f_ref, omega, self._step, t=t)
        self._times.clear()
        self._accel.clear()
        self._n = 0
        del self._readings[:-3]
        if self.progress is not None:
            x, s = self.filter.estimate, self.filter.sigma
            parts = []
            for name in self.show:
                k = PARAM_NAMES.index(name)
                unit, one = DISPLAY_UNITS[PARAM_KINDS[k]]
                parts.append(f"{name} {x[k] / one:.4g}±{s[k] / one:.2g} {unit}")
            self.progress.extra(", ".join(parts) + " (± = filter white-noise 1σ, k = 1)")


# ---- offline: recording → arrays -------------------------------------------------------------------------------------


@dataclass
class StepWindow:
    """Samples of one acquisition window with their reference (body frame, SI)."""

    name: str
    kind: str
    t: NDArray[np.float64]
    f_out: NDArray[np.float64]
    f_ref: NDArray[np.float64]
    omega: NDArray[np.float64]
    angles: NDArray[np.float64] | None = None


@dataclass
class RecordedRun:
    """What identification needs from a recording."""

    path: Path
    attrs: dict[str, Any]
    config: BenchConfig
    windows: list[StepWindow]
    warmup_accel: NDArray[np.float64] | None
    truth: dict[str, float] | None
    incomplete_steps: list[str]
    temperature: NDArray[np.float64]
    time_base: TimeBase = IDENTITY
    table: Any = None  # the readings on the unit's clock (benches.recording.TableReadings)


ACCEL_INVALID = 0b111
"""``/imu/status`` bits of the accelerometer channels (bit set = sample invalid,
drivers.imu_unit.description.FLAG_BITS): flagged samples are left out of the identification, never silently used."""


def load_run(run: str | Path, time_base: str = "estimate") -> RecordedRun:
    """Read a recording's acquisition windows and reference; clear errors for unusable recordings.

    The recording is verified first (every checksum): identification never runs on damaged data.
    """
    try:
        rec = open_recording(run)
    except RecordingError as exc:
        raise IdentificationError(str(exc)) from None
    path = rec.path
    with rec:
        hdr = rec.header
        attrs = hdr.as_dict()
        attrs["integrity_verified"] = rec.integrity_verified
        attrs["integrity_note"] = rec.integrity_note
        bench_text = rec.bench_text
        if not bench_text or rec.n_table == 0:
            raise IdentificationError(f"{path}: the recording lacks its bench text, samples or table readings")
        config = load_bench_text(bench_text, f"{path}:/bench_yaml")
        steps = rec.steps
        if not steps:
            raise IdentificationError(f"{path}: no completed step in the recording (was the run stopped at once?)")
        n = rec.n_samples
        latency = unit_latency(config)
        if time_base == "none":
            tb = TimeBase(method="none (not estimated: table and unit times taken as one clock)")
        else:
            tb = run_time_base(
                rec, rec.table(), g=config.site.g, mounting=config.unit.mounting, latency=latency,
                declared=getattr(config.unit, "time_reference", None),
            )  # fmt: skip
        table = table_in_unit_time(rec.table(), tb)  # every reference on the unit's clock
        windows: list[StepWindow] = []
        warm: NDArray[np.float64] | None = None
        incomplete = [s.name for s in steps if s.status != "complete"]
        for s in steps:
            if s.status != "complete" or s.acq_end <= s.acq_start:
                continue
            if s.kind == Warmup.kind:
                warm = rec.samples(s.acq_start, s.acq_end, ("accel",)).accel
                continue
            if s.kind not in _IDENTIFIED_KINDS:
                continue
            smp = rec.samples(s.acq_start, s.acq_end, ("time", "accel", "status"))
            t, fo, st = smp.time, smp.accel, smp.status
            assert t is not None and fo is not None and st is not None
            valid = (st & ACCEL_INVALID) == 0  # flagged by the unit
            if not valid.all():
                t, fo = t[valid], fo[valid]
                if t.size == 0:
                    continue
            span = acquisition_span(float(t[0]), float(t[-1]), latency, float(config.unit.sample_rate))
            fr, om, ang = reference_for_samples(
                t, table.time, table.angles, table.rates, g=config.site.g, mounting=config.unit.mounting,
                latency=latency, span=span,
            )  # fmt: skip
            windows.append(StepWindow(s.name, s.kind, t, fo, fr, om, ang))
        tr = rec.truth()
        truth = None
        if tr is not None and all(n_ in tr.parameters for n_ in PARAM_NAMES):
            truth = {n_: float(tr.parameters[n_]) for n_ in PARAM_NAMES}
        temp = rec.samples(fields=("temperature",), index=np.arange(0, n, max(1, n // 10000))).temperature
        temp = temp if temp is not None else np.zeros(0)
    if not windows:
        raise IdentificationError(
            f"{path}: no complete hold or spin step to identify from (procedure {attrs.get('procedure_name')!r}); "
            "run a calibration procedure such as ten-step"
        )
    return RecordedRun(path, attrs, config, windows, warm, truth, incomplete, temp, tb, table)


def _windows_as_plan_steps(windows: list[StepWindow], max_points: int = 4000) -> list[PlanStep]:
    out = []
    for w in windows:
        m = w.f_ref.shape[0]
        if w.kind == "hold":
            out.append(PlanStep(w.name, w.f_ref.mean(0, keepdims=True), w.omega.mean(0, keepdims=True), np.array([m])))
        else:
            k = max(1, math.ceil(m / max_points))
            idx = np.arange(0, m, k)
            wts = np.full(idx.size, float(k))
            wts[-1] = m - k * (idx.size - 1)
            out.append(PlanStep(w.name, w.f_ref[idx], w.omega[idx], wts))
    return out


def _display(k: int, value: float) -> float:
    return value / DISPLAY_UNITS[PARAM_KINDS[k]][1]


def _time_base_covariance(
    rr: RecordedRun, r_var: NDArray[np.float64], p0: NDArray[np.float64]
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The identified parameters' covariance from the time base's uncertainty, J Σ Jᵀ, and J = ∂x/∂(t₀, ε) (18, 2)."""
    tb = rr.time_base
    cov = np.asarray(tb.covariance, dtype=float)
    n = len(PARAM_NAMES)
    if rr.table is None or not np.all(np.isfinite(cov)) or not np.any(cov):
        return np.zeros((n, n)), np.zeros((n, 2))
    cfg = rr.config
    lat = unit_latency(cfg)
    fs = float(cfg.unit.sample_rate)
    wins = [(w.t, w.f_out, acquisition_span(float(w.t[0]), float(w.t[-1]), lat, fs)) for w in rr.windows]
    jac = time_base_sensitivity(
        wins, rr.table, g=cfg.site.g, mounting=cfg.unit.mounting, latency=lat, r_var=r_var, p0=p0
    )
    return jac @ cov @ jac.T, jac


def _time_base_warnings(rr: RecordedRun) -> list[str]:
    """Lines for calibration.json's warnings: a timing misfit beyond what the budget carries (naming its cause),
    a host-clock check that disagrees, a time base that could not be measured.

    Within a motion the budget carries a reading's timing error up to the table's attitude accuracy (its
    rectangular u) over the run's fastest rate (analysis.timebase.misfit_cause)."""
    tb = rr.time_base
    out = [n for n in tb.notes if "disagrees" in n or "without a stated uncertainty" in n]
    host = tb.check.get("table_stamped_by") == "host"
    w_max = float(np.max(np.abs(rr.table.rates))) if rr.table is not None and len(rr.table) else 0.0
    att = float(rr.config.turntable.attitude_accuracy) / math.sqrt(3.0)
    cause = misfit_cause(tb, host_stamped=host, carried=att / w_max if w_max > 0 else math.inf)
    if cause:
        out.append(cause)
    return out


def _time_base_block(tb: TimeBase, p_time: NDArray[np.float64], jac: NDArray[np.float64]) -> dict[str, Any]:
    """calibration.json's ``time_base``: the estimate, its u, the method, its effect on each parameter (u, SI,
    included in the covariance) and on a gyro scale factor (ε 1:1)."""
    d = tb.as_dict()
    d["effect_u"] = {n: float(math.sqrt(max(p_time[k, k], 0.0))) for k, n in enumerate(PARAM_NAMES)}
    d["sensitivity"] = {n: [float(jac[k, 0]), float(jac[k, 1])] for k, n in enumerate(PARAM_NAMES)}
    for k in ("u_offset_s", "u_rate", "misfit"):
        if not math.isfinite(d[k]):
            d[k] = None
    d["covariance"] = [[x if math.isfinite(x) else None for x in row] for row in d["covariance"]]
    d["gyro_scale_factor_u"] = d["u_rate"]  # a gyro scale factor measured as angle over time inherits ε 1:1
    return d


def identify_run(
    run: str | Path, method: str = "kalman", noise: str = "configured", time_base: str = "estimate"
) -> CalibrationResult:
    """Identify the 18 parameters from a recording; returns the typed calibration result.

    Parameters
    ----------
    run : path
        Run folder or recording file.
    method : {"kalman", "batch"}
        The streaming filter over all windows in order, or batch least squares (same prior, same model).
    noise : {"configured", "warm-up"}
        R from the bench's configured VRW, or estimated from the run's warm-up record.
    time_base : {"estimate", "none"}
        Map the table's clock to the unit's with the run's estimated time base (benches.timebase), or take
        them as one clock (what the live filter during the run does; for comparisons).
    """
    if method not in ("kalman", "batch"):
        raise IdentificationError(f"unknown method {method!r}; use kalman or batch")
    if time_base not in ("estimate", "none"):
        raise IdentificationError(f"unknown time base {time_base!r}; use estimate or none")
    rr = load_run(run, time_base)
    config = rr.config
    p0 = prior_covariance(config)
    if noise == "configured":
        r_var = configured_noise_variance(config)
    elif noise == "warm-up":
        if rr.warmup_accel is None or rr.warmup_accel.shape[0] < 100:
            raise IdentificationError(f"{rr.path}: no warm-up record to estimate R from; use --noise configured")
        r_var = estimate_measurement_noise(rr.warmup_accel)
    else:
        raise IdentificationError(f"unknown noise source {noise!r}; use configured or warm-up")
    history = None
    if method == "kalman":
        kf = StreamingIdentifier(r_var, p0, sample_rate=config.unit.sample_rate)
        for w in rr.windows:
            kf.update(w.f_out, w.f_ref, w.omega, w.name, t=w.t)
        x, p_white, info = kf.estimate, kf.covariance, kf.information
        resid = kf.residual_statistics()
        per_step = [
            {"name": name, "samples": int(st.count), "mean": list(map(float, st.mean)), "rms": list(map(float, st.rms))}
            for name, st in resid.items()
        ]
        history = {
            "time": [h.time for h in kf.history],
            "step": [h.step for h in kf.history],
            "estimate": [list(map(float, h.x)) for h in kf.history],
            "sigma": [list(map(float, h.sigma)) for h in kf.history],
        }
    else:
        res = batch_identify(
            np.concatenate([w.f_out for w in rr.windows]),
            np.concatenate([w.f_ref for w in rr.windows]),
            np.concatenate([w.omega for w in rr.windows]),
            r_var,
            None,
            p0,
        )
        x, p_white, info = res.x, res.covariance, res.information
        per_step = []
        for w in rr.windows:
            r = w.f_out - predict(x, w.f_ref, w.omega)
            per_step.append(
                {
                    "name": w.name,
                    "samples": int(r.shape[0]),
                    "mean": list(map(float, r.mean(0))),
                    "rms": list(map(float, np.sqrt((r**2).mean(0)))),
                }
            )
    kinds = {w.name: w.kind for w in rr.windows}
    for s in per_step:
        s["kind"] = kinds.get(s["name"], "")
    # honest total uncertainty: white + bias-instability systematic term, on the actual data geometry
    b = bias_stability(config)
    actual = plan_identification(
        _windows_as_plan_steps(rr.windows),
        r_var,
        p0,
        b,
        offset_covariance=offset_covariance([(float(w.t[0]), float(w.t[-1])) for w in rr.windows], b),
    )
    p_total = p_white + (actual.covariance_total - actual.covariance_white)
    p_time, jac_time = _time_base_covariance(rr, r_var, p0)
    p_total = p_total + p_time
    p_total = 0.5 * (p_total + p_total.T)
    sigma = np.sqrt(np.diag(p_total))
    sigma_white = np.sqrt(np.diag(p_white))
    rank, cond = information_rank(info, r_var)
    unobs = set(unobservable_parameters(info, r_var)) | set(actual.unidentifiable)
    params: dict[str, Any] = {}
    for k, name in enumerate(PARAM_NAMES):
        kind = PARAM_KINDS[k]
        unit, _one = DISPLAY_UNITS[kind]
        params[name] = {
            "value": float(x[k]),
            "u": float(sigma[k]),
            "u_white": float(sigma_white[k]),
            "unit": _SI_UNITS[kind],
            "kind": kind,
            "display_unit": unit,
            "display_value": _display(k, x[k]),
            "display_u": _display(k, sigma[k]),
            "identified": name not in unobs,
            "prior_sigma": float(math.sqrt(p0[k, k])),
        }
    n_s = np.array([st["samples"] for st in per_step], dtype=float)
    ms_s = np.array([st["rms"] for st in per_step]) ** 2
    rms_all = np.sqrt((n_s[:, None] * ms_s).sum(0) / n_s.sum())
    truth_block = None
    if rr.truth is not None:
        xt = np.array([rr.truth[n_] for n_ in PARAM_NAMES])
        err = x - xt
        ident = np.array([params[n_]["identified"] for n_ in PARAM_NAMES])
        idx = np.flatnonzero(ident)
        sub = p_total[np.ix_(idx, idx)]
        nees = float(err[idx] @ np.linalg.solve(sub, err[idx]))
        truth_block = {
            "values": rr.truth,
            "error_over_u": {n_: float(err[k] / sigma[k]) for k, n_ in enumerate(PARAM_NAMES)},
            "nees": nees,
            "dof": int(idx.size),
            "nees_states": [PARAM_NAMES[i] for i in idx],
        }
    warnings = list(actual.warnings)
    warnings += _time_base_warnings(rr)
    if rr.incomplete_steps:
        warnings.insert(0, f"recording incomplete: step(s) {', '.join(rr.incomplete_steps)} not completed")
    if not rr.attrs.get("integrity_verified", False):
        warnings.insert(0, str(rr.attrs.get("integrity_note") or "recording integrity cannot be verified"))
    a = rr.attrs
    temp = rr.temperature
    result = {
        "format": "tablebench-calibration",
        "format_version": 2,
        "recording": rr.path.name,
        "recording_sha256": file_sha256(rr.path),
        "software_version": str(a.get("software_version", "")),
        "method": method,
        "model": MODEL_TEXT,
        "parameter_names": list(PARAM_NAMES),
        "parameters": params,
        "covariance": [list(map(float, row)) for row in p_total],
        "covariance_white": [list(map(float, row)) for row in p_white],
        "information": {
            "rank": int(rank),
            "condition": float(cond),
            "unidentifiable": sorted(unobs, key=PARAM_NAMES.index),
            "tolerance": "numerical rank of the noise-whitened data information, scaled per parameter kind "
            "(analysis.identification.batch.information_rank)",
        },
        "measurement_noise": {"variance": list(map(float, r_var)), "source": noise},
        "residuals": {"rms": list(map(float, rms_all)), "per_step": per_step},
        "plan": {
            "predicted_sigma": {n_: float(actual.sigma_total[k]) for k, n_ in enumerate(PARAM_NAMES)},
            "rank": int(actual.rank),
            "warnings": list(actual.warnings),
        },
        "truth": truth_block,
        "time_base": _time_base_block(rr.time_base, p_time, jac_time),
        "history": history,
        "run": {
            "status": str(a.get("status", "")),
            "bench_name": str(a.get("bench_name", "")),
            "procedure_name": str(a.get("procedure_name", "")),
            "procedure_sha256": str(a.get("procedure_sha256", "")),
            "procedure_overrides": dict(a.get("procedure_overrides") or {}),
            "integrity_verified": bool(a.get("integrity_verified", False)),
            "integrity_note": str(a.get("integrity_note", "")),
            "seed": -1 if a.get("seed") is None else int(a["seed"]),
            "created_utc": str(a.get("created_utc", "")),
            "transport": str(a.get("transport", "")),
            "site": {
                "name": config.site.name,
                "latitude_deg": math.degrees(config.site.latitude),
                "height_m": config.site.height,
                "g": config.site.g,
                "g_source": config.site.g_source,
            },
            "unit": {"model": config.unit.model, "serial_number": config.unit.serial_number},
            "table": {
                "model": config.turntable.model,
                "serial_number": config.turntable.serial_number,
                "attitude_accuracy": config.turntable.attitude_accuracy,
            },
            "temperature_k": {
                "mean": float(temp.mean()) if temp.size else None,
                "min": float(temp.min()) if temp.size else None,
                "max": float(temp.max()) if temp.size else None,
            },
        },
        "warnings": warnings,
    }
    if not (np.all(np.isfinite(x)) and np.all(np.isfinite(p_total)) and np.all(np.isfinite(p_white))):
        raise IdentificationError(
            f"{rr.path}: the identification produced non-finite estimates or covariance (damaged data?); "
            "nothing was written"
        )
    return CalibrationResult.from_dict(result, str(rr.path))


def write_calibration(result: CalibrationResult, out: str | Path) -> Path:
    """Write ``calibration.json`` (strict: a non-finite number raises; :meth:`CalibrationResult.save`)."""
    return result.save(out)

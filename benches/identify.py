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

import contextlib
import dataclasses
import math
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from analysis.columns import column_means, side_by_side
from analysis.identification.batch import batch_identify, information_rank, unobservable_parameters
from analysis.identification.bias_drift import flicker_components, window_mean_covariance
from analysis.identification.kalman import StreamingIdentifier, estimate_measurement_noise
from analysis.identification.plan import IdentificationPlan, PlanStep, plan_identification
from analysis.identification.specification import ModelSpec, UnitModel, get_model
from analysis.timebase import IDENTITY, TimeBase, misfit_cause
from analysis.units import ARCSEC, DEG, DEG_PER_HOUR, DISPLAY_UNITS, G0, PPM
from core.errors import UserError
from drivers.protocols import ImuBlock, TableState
from procedures.steps import CompiledProcedure, Hold, Spin, Step, Warmup
from procedures.trajectory import nominal_samples

from .bench_config import BenchConfig, noise_problem
from .calibration_result import (
    CalibrationResult,
    FilterHistory,
    InformationSummary,
    ParameterEstimate,
    PlanSummary,
    Residuals,
    RunInfo,
    StepResiduals,
    TimeBaseBlock,
    TruthCheck,
)
from .progress import ProgressDisplay
from .recorded_run import RecordedRun, run_of
from .recording import RecordingError, StepRecord, TableReadings, file_identity, recording_file
from .reference import acquisition_span, earth_in_body, reference_at, reference_for_window
from .timebase import reference_rate_covariance, run_time_base, table_in_unit_time, time_base_sensitivity

ACCEL_MODEL: ModelSpec = get_model("accelerometer")
"""The accelerometer model (:mod:`analysis.identification.specification` registry)."""
GYRO_PRIOR_DEFAULT: dict[str, float] = {
    "gyro_bias": 10.0 * DEG_PER_HOUR,
    "gyro_scale": 1000.0 * PPM,
    "gyro_misalignment": 100.0 * ARCSEC,
    "g_sensitivity": 1.0 * DEG_PER_HOUR / G0,
    "gyro_quadratic": 10.0 * PPM / DEG,
    "gyro_asymmetry": 1000.0 * PPM,
}
"""Gyro prior 1σ per kind (SI) when the bench file states none: a tactical-grade datasheet (10 °/h, 1000 ppm,
100″, 1 °/h/g); the calibration result warns that they were used."""
IDENTIFIED_STEPS: tuple[type[Step], ...] = (Hold, Spin)
"""Steps whose counted samples the identification fits (a warm-up's only estimate the noise)."""
_IDENTIFIED_KINDS = frozenset(t.kind for t in IDENTIFIED_STEPS)  # as written in a recording's steps table


class IdentificationError(UserError, RuntimeError):
    """The recording cannot be identified; the message says why and what to do."""


# ---- bench → prior and noise ------------------------------------------------------------------------------------


def unit_model(config: BenchConfig, with_gyro: bool = True) -> ModelSpec:
    """The model identified for the bench's unit: accelerometer, plus the gyro model when there are gyros.

    The gyro's g-sensitivity is the full 3 × 3 matrix when the bench asks for it
    (``unit.gyro_g_sensitivity: full``), else its diagonal.
    """
    if not with_gyro:
        return ACCEL_MODEL
    full = str(getattr(config.unit, "gyro_g_sensitivity", "diagonal")) == "full"
    return UnitModel((ACCEL_MODEL, get_model("gyro", full_g=True) if full else get_model("gyro")))


def prior_covariance(config: BenchConfig, model: ModelSpec | None = None) -> NDArray[np.float64]:
    """P0 = diag(σ²) from the bench's ``unit.prior`` (datasheet 1σ per parameter, SI).

    The accelerometer's 18 must be given; a gyro parameter the bench does not state takes the tactical-grade
    default of its kind (:data:`GYRO_PRIOR_DEFAULT`, see :func:`defaulted_priors`).
    """
    m = ACCEL_MODEL if model is None else model
    prior = config.unit.prior
    missing = [n for n in ACCEL_MODEL.names if n not in prior]
    if missing:
        raise IdentificationError(
            f"bench {config.name!r}: unit prior lacks {', '.join(missing)}; give a datasheet 1σ for all 18 parameters"
        )
    sig = [float(prior.get(n, GYRO_PRIOR_DEFAULT.get(k, math.nan))) for n, k in zip(m.names, m.kinds, strict=True)]
    return np.diag(np.square(sig))


def defaulted_priors(config: BenchConfig, model: ModelSpec) -> list[str]:
    """Names whose prior is the default of :data:`GYRO_PRIOR_DEFAULT` (the bench file states none)."""
    return [n for n in model.names if n not in config.unit.prior]


def configured_noise_variance(config: BenchConfig, model: ModelSpec | None = None) -> NDArray[np.float64]:
    """Per-sample white-noise variance per axis: VRW² × sample rate, (m/s²)², then ARW² × rate, (rad/s)²."""
    fs = float(config.unit.sample_rate)
    acc = np.asarray(config.unit.noise.vrw, dtype=float) ** 2 * fs
    if model is None or model.n_axes == 3:
        return acc
    problem = noise_problem(config)  # the one rule, shared with check, plan and run
    if problem is not None:
        raise IdentificationError(problem)
    arw = np.asarray(config.unit.noise.arw, dtype=float)
    return np.concatenate([acc, arw**2 * fs])


def unit_latency(config: BenchConfig) -> float:
    """The unit's output latency (group delay of its anti-alias filter), s, from the bench file (0 if absent).

    The sample stamped t measures the specific force of about t − latency, so the table reference is
    evaluated there; during a spin at ω an unaccounted latency δ turns the reference by ω·δ.
    """
    return float(getattr(config.unit, "latency", 0.0) or 0.0)


def bias_stability(config: BenchConfig, model: ModelSpec | None = None) -> NDArray[np.float64]:
    """Bias instability per axis (the per-step unmodelled DC offset of the error budget): m/s², then rad/s."""
    acc = np.asarray(config.unit.noise.bias_instability, dtype=float)
    if model is None or model.n_axes == 3:
        return acc
    return np.concatenate([acc, np.asarray(config.unit.noise.gyro_bias_instability, dtype=float)])


def angle_over_time(
    t: NDArray[np.float64],
    table_time: NDArray[np.float64],
    table_angles: NDArray[np.float64],
    span: tuple[float, float],
) -> NDArray[np.float64] | None:
    """Gimbal rates (3,) rad/s of a spin: the encoder angle between the span's first and last reading over
    the time between them — the gyro's scale reference, not a commanded or reported rate; end to end, as the
    gyro's mean sees the table's rate jitter (docs/methods/gyro-calibration.md). None: < 2 readings."""
    keep = np.flatnonzero((table_time >= span[0]) & (table_time <= span[1]))
    if keep.size < 2:
        return None
    i, j = int(keep[np.argmin(table_time[keep])]), int(keep[np.argmax(table_time[keep])])
    dt = float(table_time[j] - table_time[i])
    if not dt > 0:
        return None
    return (table_angles[j] - table_angles[i]) / dt


def window_reference(
    t: NDArray[np.float64],
    table_time: NDArray[np.float64],
    table_angles: NDArray[np.float64],
    table_rates: NDArray[np.float64],
    config: BenchConfig,
    latency: float,
    span: tuple[float, float],
    spin: bool,
    clock_rate: float = 0.0,
    with_earth: bool = True,
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], NDArray[np.float64] | None]:
    """The reference of one acquisition window (body frame, SI): f_ref, table rate ω, angles, and ``earth``
    (None unless ``with_earth``: only the gyro reference uses it).

    ``earth`` is what the gyro reference adds to ω: the Earth rate C_n^b Ω^n at the site. During a spin ω is
    the table rate from the encoder angles' slope over the window (:func:`angle_over_time`) for both triads
    (the gyro's scale and the accelerometers' centripetal term), not the reported rate: a table turns at
    (1 + ε) × its command and only its angles say by how much. ``clock_rate`` is the factor from
    the readings' time scale to true time: with the readings on the unit's clock (t_unit = (t_table − t₀)/(1+ε))
    and the controller's clock running (1 + ε_c) fast against the host's, the slope over unit time is
    multiplied by (1 + ε_c)/(1 + ε) − 1 + 1 (:func:`reference_clock_factor`): the rate is per second of the
    bench's reference clock, not of the unit's or the controller's.
    """
    mnt = config.unit.mounting
    slope = angle_over_time(t, table_time, table_angles, span) if spin else None
    if slope is not None:
        slope = slope * (1.0 + clock_rate)
    fr, om, ang, trig, _ = reference_for_window(  # each angle's sine and cosine once for the window's rotations
        t, table_time, table_angles, table_rates, g=config.site.g, mounting=mnt, latency=latency, span=span,
        gimbal_rates=slope,
    )  # fmt: skip
    earth = earth_in_body(ang, config.site.latitude, mnt, trig=trig) if with_earth else None
    return fr, om, ang, earth


def offset_covariance(windows: list[tuple[float, float]], b: NDArray[np.float64]) -> NDArray[np.float64]:
    """(axes, K, K) covariance of the step-mean bias offsets over K acquisition windows (bench s), per axis.

    The unit's bias instability B (bench file) as flicker noise (:mod:`analysis.identification.bias_drift`): correlated
    between steps, so slow wander across a sequence of positions is propagated, not assumed independent.
    """
    starts = np.array([w[0] for w in windows])
    ends = np.array([w[1] for w in windows])
    out = np.zeros((b.size, len(windows), len(windows)))
    for axis in range(b.size):
        if b[axis] > 0:
            out[axis] = window_mean_covariance(starts, ends, *flicker_components(float(b[axis])))
    return out


# ---- the pre-run plan ------------------------------------------------------------------------------------------------


def _plan_steps_and_windows(
    compiled: CompiledProcedure, config: BenchConfig, sample_rate: float | None = None
) -> list[tuple[PlanStep, tuple[float, float]]]:
    lat, mnt = config.site.latitude, config.unit.mounting
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
        earth = earth_in_body(ns.angles, lat, mnt)
        out.append((PlanStep(ns.step.name, f_ref, omega, ns.weights, ns.angles, earth), window[ns.step.name]))
    if not out:
        raise IdentificationError(f"procedure {compiled.name!r} has no hold or spin to identify from")
    return out


def plan_for(compiled: CompiledProcedure, config: BenchConfig, model: ModelSpec | None = None) -> IdentificationPlan:
    """Predicted 1σ of every parameter for a procedure on a bench, before any motion.

    White noise from the bench's VRW (and ARW), prior from its datasheet bounds, and the bias instability
    as correlated flicker between the steps' nominal acquisition windows (:func:`offset_covariance`). The
    model defaults to the unit's (:func:`unit_model`: accelerometer + gyro).
    """
    m = unit_model(config) if model is None else model
    pairs = _plan_steps_and_windows(compiled, config)
    b = bias_stability(config, m)
    return plan_identification(
        [p for p, _ in pairs],
        configured_noise_variance(config, m),
        prior_covariance(config, m),
        b,
        offset_covariance=offset_covariance([w for _, w in pairs], b),
        model=m,
    )


# ---- live identification during the run ---------------------------------------------------------------------------


class LiveIdentifier:
    """Runner observer feeding the streaming Kalman filter as the run goes.

    Samples of the acquisition windows are buffered and fused every ``update_seconds`` of data and at each
    step end (one exact information-form update per batch: with Q = 0 grouping samples changes nothing).
    The reference for the buffered samples interpolates the table readings taken during (and just before)
    the buffer at the sample times less the unit's latency — the same readings offline identification
    interpolates. The live filter cannot know the run's time base before its motions are over, so it takes
    the table's and the unit's clocks as one: on a one-clock bench it equals offline identification with
    ``time_base="none"``; calibration.json maps the clocks with the estimated time base. A spin is fused
    once, at its end: its gyro reference rate is the slope of the encoder angles over the whole acquisition
    (:func:`window_reference`). The model is the unit's (:func:`unit_model`), with the gyro when ``with_gyro``.
    """

    def __init__(
        self,
        config: BenchConfig,
        progress: ProgressDisplay | None = None,
        show: tuple[str, ...] = ("b_z", "S_z", "r_x"),
        update_seconds: float = 10.0,
        with_gyro: bool = True,
    ) -> None:
        self.config = config
        self.model = m = unit_model(config, with_gyro)
        self.filter = StreamingIdentifier(
            configured_noise_variance(config, m), prior_covariance(config, m), sample_rate=config.unit.sample_rate,
            model=m,
        )  # fmt: skip
        self.latency = unit_latency(config)
        self.progress = progress
        self.show = show
        self._flush_n = max(1, int(update_seconds * config.unit.sample_rate))
        self._readings: list[TableState] = []
        self._times: list[NDArray[np.float64]] = []
        self._accel: list[NDArray[np.float64]] = []
        self._gyro: list[NDArray[np.float64]] = []
        self._n = 0
        self._step: str | None = None
        self._spin = False
        self._acq_t0 = 0.0
        self._unseen: tuple[int, set[str]] | None = None

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
        self._spin = isinstance(step, Spin)
        self._times.append(block.time)
        self._accel.append(block.accel)  # joined at the update (one copy per update, not per block)
        if self.model.n_axes == 6:
            self._gyro.append(block.gyro)
        self._n += len(block)
        if self._n >= self._flush_n and not self._spin:
            self.flush()

    def unseen(self) -> set[str]:
        """Parameters the motion so far does not see (their estimate is only the prior's): shown as "not identified
        yet", never as a number, in the progress line and the live view (worked out once per filter update, when
        asked)."""
        n = self.filter.n_samples
        if self._unseen is None or self._unseen[0] != n:
            names = unobservable_parameters(self.filter.information, self.filter.r_var, model=self.model)
            self._unseen = (n, set(names))
        return set(self._unseen[1])

    def parameter_kinds(self) -> list[tuple[str, str]]:
        """(name, quantity kind) of every state the filter estimates, in its order (for the live view)."""
        m = self.filter.model
        return list(zip(m.names, m.kinds, strict=True))

    def on_step_end(self, step: Step, record: StepRecord) -> None:
        """Fuse what is buffered for the step."""
        self.flush()

    def flush(self) -> None:
        """Fuse the buffered samples in one exact filter update and refresh the live display."""
        if self._n == 0 or self._step is None:
            return
        t = np.concatenate(self._times)
        rd = self._readings
        f_ref, omega, _ang, earth = window_reference(
            t,
            np.array([r.time for r in rd]),
            np.stack([r.angles for r in rd]),
            np.stack([r.rates for r in rd]),
            self.config,
            self.latency,
            acquisition_span(self._acq_t0, float(t[-1]), self.latency, float(self.config.unit.sample_rate)),
            self._spin,
        )
        out = np.concatenate(self._accel)
        if self.model.n_axes == 6:
            out = np.hstack([out, np.concatenate(self._gyro)])
        self.filter.update(out, f_ref, omega, self._step, t=t, earth=earth)
        self._times.clear()
        self._accel.clear()
        self._gyro.clear()
        self._n = 0
        del self._readings[:-3]
        if self.progress is not None:
            self.progress.extra(self.estimates_text)  # composed only when the progress line is shown

    def estimates_text(self) -> str:
        """The progress line's live estimates: ``show``'s parameters ± the filter's white-noise 1σ, or "not
        identified yet" where the motion so far does not see one. A preview: the live filter takes the unit's and
        the table's clocks as one (the run's time base is estimated after the motions), so on a two-clock bench
        its scale factors and misalignments can differ from calibration.json's by far more than the ± shown
        (benches/CALIBRATION_FORMAT.md, ``live_vs_offline_max_u``)."""
        x, s = self.filter.estimate, self.filter.sigma
        unseen = self.unseen()
        parts = []
        for name in self.show:
            k = self.model.index(name)
            unit, one = DISPLAY_UNITS[self.model.kinds[k]]
            if name in unseen:  # the motion so far does not see it: its value is only the prior's
                parts.append(f"{name} not identified yet")
                continue
            parts.append(f"{name} {x[k] / one:.4g}±{s[k] / one:.2g} {unit}")
        return ", ".join(parts) + " (preview, clocks taken as one until the time base; ± = white-noise 1σ, k = 1)"


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
    gyro: NDArray[np.float64] | None = None
    """Gyro output (n, 3), rad/s, body frame (None: accelerometer only)."""
    earth: NDArray[np.float64] | None = None
    """What the gyro reference adds to ``omega`` (n, 3), rad/s: Earth rate (+ the spin's angle-over-time rate)."""

    def output_columns(self, model: ModelSpec) -> tuple[NDArray[np.float64], ...]:
        """The unit's output for ``model`` as the arrays whose columns side by side are it, not copied into one:
        (accelerometer,) or (accelerometer, gyro) (the filter's update and the Gram take them so)."""
        assert model.n_axes == 3 or self.gyro is not None
        return (self.f_out,) if model.n_axes == 3 else (self.f_out, self.gyro)  # type: ignore[return-value]

    def output(self, model: ModelSpec) -> NDArray[np.float64]:
        """The unit's output for ``model`` in one array: accelerometer (n, 3), or with the gyro side by side (n, 6)."""
        cols = self.output_columns(model)
        return cols[0] if len(cols) == 1 else side_by_side(list(cols))


@dataclass
class IdentificationData:
    """What identification needs from a recorded run: the acquisition windows with their reference."""

    run: RecordedRun
    windows: list[StepWindow]
    warmup_accel: NDArray[np.float64] | None
    truth: dict[str, float] | None
    incomplete_steps: list[str]
    temperature: NDArray[np.float64]
    time_base: TimeBase = IDENTITY
    table: TableReadings | None = None  # the readings on the unit's clock (benches.recording.TableReadings)
    warmup_gyro: NDArray[np.float64] | None = None
    model: ModelSpec = ACCEL_MODEL
    """The model identified from this recording (:func:`unit_model`: with the gyro when it has gyro data)."""

    @property
    def path(self) -> Path:
        """The recording file."""
        return self.run.path

    @property
    def config(self) -> BenchConfig:
        """The recorded bench, parsed once (:attr:`RecordedRun.config`)."""
        return self.run.config


ACCEL_INVALID = 0b111
"""``/imu/status`` bits of the accelerometer channels (bit set = sample invalid,
drivers.imu_unit.description.FLAG_BITS): flagged samples are left out of the identification, never silently used."""
GYRO_INVALID = 0b111000
"""``/imu/status`` bits of the gyro channels (with the gyro model, a row with either triad flagged is left out)."""


def load_run(
    run: str | Path | RecordedRun, time_base: str = "estimate", with_gyro: bool | None = None
) -> IdentificationData:
    """Read a recording's acquisition windows and reference; clear errors for unusable recordings.

    ``run`` is a run folder, a recording file or an open :class:`RecordedRun` (left open). The recording is
    verified when it is opened (every checksum): identification never runs on damaged data. ``time_base``:
    "estimate" puts the table's readings on the unit's clock with the run's estimated time base
    (benches.timebase), "none" takes the two clocks as one. ``with_gyro``: identify the gyro triad too
    (default: when the recording has gyro data, :func:`has_gyro_data`).
    """
    key = _data_key(run, time_base, with_gyro)
    if key is not None and _RECENT.get("key") == key:
        return _RECENT["data"]
    with _opened(run) as rr:
        return _identification_data(rr, time_base, with_gyro)


_RECENT: dict[str, Any] = {}
"""The identification data of the last :func:`identify_run` of this process, with its key (:func:`_data_key`):
the registry's as found / as left (:func:`load_run` of the same run folder right after ``run`` or ``identify``
identified it) takes the windows from here instead of reading and referencing the recording again."""


def recent_data(run: str | Path) -> IdentificationData | None:
    """The identification data of the last :func:`identify_run` of this process when it was of ``run`` (a run
    folder or recording; the same, unchanged file) with the defaults, else None — nothing is read. What the
    registry's record of the run just identified reuses (its bench text) instead of opening the recording again."""
    key = _data_key(run, "estimate", None)
    return _RECENT["data"] if key is not None and _RECENT.get("key") == key else None


def _data_key(run: str | Path | RecordedRun, time_base: str, with_gyro: bool | None) -> tuple | None:
    """(recording file, its identity: device, inode, size, modification and change times in ns, the options);
    None when it cannot be stated (then nothing is remembered or taken)."""
    try:
        path = run.path if isinstance(run, RecordedRun) else recording_file(run)
        ident = file_identity(path)
    except (OSError, ValueError, TypeError):
        return None
    return (str(Path(path).resolve()), ident, time_base, with_gyro)


@contextlib.contextmanager
def _opened(run: str | Path | RecordedRun) -> Iterator[RecordedRun]:
    """:func:`benches.recorded_run.run_of` with a recording that cannot be opened as IdentificationError."""
    with contextlib.ExitStack() as stack:
        try:
            rr = stack.enter_context(run_of(run))
        except RecordingError as exc:
            raise IdentificationError(str(exc)) from None
        yield rr


def has_gyro_data(rec: Any, steps: Sequence[StepRecord]) -> bool:
    """True when the gyro channels carry data in the first identified window (not all flagged, not all 0)."""
    for s in steps:
        if s.status == "complete" and s.kind in _IDENTIFIED_KINDS and s.acq_end > s.acq_start:
            stop = min(int(s.acq_end), int(s.acq_start) + 1000)
            smp = rec.samples(s.acq_start, stop, ("gyro", "status"))
            ok = (smp.status & GYRO_INVALID) == 0
            return bool(np.any(ok) and np.any(smp.gyro[ok] != 0.0))
    return False


def reference_clock_factor(tb: TimeBase) -> float:
    """(1 + ε_c)/(1 + ε) − 1: from a slope over unit time (readings mapped by the time base, ε) to a slope over
    the host's clock (the controller clock's rate against the host's, ε_c, from the time base's check; 0 when
    the run has none). The host clock is the bench's reference second (NTP-disciplined on a real bench)."""
    eps = float(tb.rate) if np.isfinite(tb.rate) else 0.0
    eps_c = tb.check.get("controller_vs_host_rate") if isinstance(tb.check, dict) else None
    eps_c = float(eps_c) if isinstance(eps_c, int | float) and np.isfinite(eps_c) else 0.0
    return (1.0 + eps_c) / (1.0 + eps) - 1.0


def _read_window(
    rec: Any, s: StepRecord, config: BenchConfig, table: Any, with_gyro: bool, clock_rate: float = 0.0
) -> StepWindow | None:
    """One hold/spin acquisition window with its reference (flagged samples left out); None when all flagged."""
    latency = unit_latency(config)
    smp = rec.samples(s.acq_start, s.acq_end, ("time", "accel", "status") + (("gyro",) if with_gyro else ()))
    t, fo, st, gy = smp.time, smp.accel, smp.status, smp.gyro
    assert t is not None and fo is not None and st is not None
    valid = (st & (ACCEL_INVALID | (GYRO_INVALID if with_gyro else 0))) == 0  # flagged by the unit
    if not valid.all():
        t, fo = t[valid], fo[valid]
        gy = None if gy is None else gy[valid]
        if t.size == 0:
            return None
    span = acquisition_span(float(t[0]), float(t[-1]), latency, float(config.unit.sample_rate))
    fr, om, _ang, earth = window_reference(  # the angles are not kept: nothing after the reference needs them
        t, table.time, table.angles, table.rates, config, latency, span, s.kind == Spin.kind, clock_rate, with_gyro
    )
    return StepWindow(s.name, s.kind, t, fo, fr, om, gy if with_gyro else None, earth)


def _identification_data(
    rr: RecordedRun, time_base: str = "estimate", with_gyro: bool | None = None
) -> IdentificationData:
    path, rec = rr.path, rr.recording
    if not rr.bench_text or rec.n_table == 0:
        raise IdentificationError(f"{path}: the recording lacks its bench text, samples or table readings")
    config = rr.config
    steps = rr.steps
    if not steps:
        raise IdentificationError(f"{path}: no completed step in the recording (was the run stopped at once?)")
    n = rec.n_samples
    latency = unit_latency(config)
    readings = rec.table()  # read once (≈ 4 ms at 15 000 readings): the time base and the reference use it
    if time_base == "none":
        tb = TimeBase(method="none (not estimated: table and unit times taken as one clock)")
    elif time_base == "estimate":
        tb = run_time_base(
            rec, readings, g=config.site.g, mounting=config.unit.mounting, latency=latency,
            declared=getattr(config.unit, "time_reference", None),
        )  # fmt: skip
    else:
        raise IdentificationError(f"unknown time base {time_base!r}; use estimate or none")
    table = table_in_unit_time(readings, tb)  # every reference on the unit's clock
    gyro = has_gyro_data(rec, steps) if with_gyro is None else with_gyro
    model = unit_model(config, gyro)
    windows: list[StepWindow] = []
    warm: NDArray[np.float64] | None = None
    warm_g: NDArray[np.float64] | None = None
    incomplete = [s.name for s in rr.incomplete_steps()]
    for s in steps:
        if s.status != "complete" or s.acq_end <= s.acq_start:
            continue
        if s.kind == Warmup.kind:
            wsmp = rec.samples(s.acq_start, s.acq_end, ("accel", "gyro"))
            warm, warm_g = wsmp.accel, wsmp.gyro
            continue
        if s.kind in _IDENTIFIED_KINDS:
            win = _read_window(rec, s, config, table, gyro, reference_clock_factor(tb))
            if win is not None:
                windows.append(win)
    tr = rec.truth()
    truth = None
    if tr is not None and all(n_ in tr.parameters for n_ in ACCEL_MODEL.names):
        truth = {n_: float(v) for n_, v in tr.parameters.items()}  # the truth check uses the model's names
    every = max(1, n // 10000)  # rows 0, every, 2·every, … (a point selection of the file decodes each chunk)
    temp = rec.samples(fields=("temperature",)).temperature  # the verified pass keeps the whole column
    temp = temp[::every].copy() if temp is not None else np.zeros(0)
    if not windows:
        raise IdentificationError(
            f"{path}: no complete hold or spin step to identify from (procedure {rr.header.procedure_name!r}); "
            "run a calibration procedure such as ten-step"
        )
    return IdentificationData(
        rr, windows, warm, truth, incomplete, temp, time_base=tb, table=table, warmup_gyro=warm_g, model=model
    )


def _windows_as_plan_steps(windows: list[StepWindow], max_points: int = 4000) -> list[PlanStep]:
    out = []
    for w in windows:
        m = w.f_ref.shape[0]
        ea = w.earth
        if w.kind == "hold":  # each column's own mean, pairwise (analysis.columns.column_means)
            mean = None if ea is None else column_means(ea)[None]
            out.append(PlanStep(w.name, column_means(w.f_ref)[None], column_means(w.omega)[None], np.array([m]),
                                earth=mean))  # fmt: skip
        else:
            k = max(1, math.ceil(m / max_points))
            idx = np.arange(0, m, k)
            wts = np.full(idx.size, float(k))
            wts[-1] = m - k * (idx.size - 1)
            out.append(PlanStep(w.name, w.f_ref[idx], w.omega[idx], wts, earth=None if ea is None else ea[idx]))
    return out


# ---- offline identification: estimate / residual statistics / truth check / result --------------------------------


@dataclass
class Estimate:
    """The estimator's output on the recorded windows (SI, model name order).

    ``filter_residuals``: the streaming filter's own per-step residual statistics (Kalman), None for batch.
    """

    method: str
    noise_variance: NDArray[np.float64]
    noise_source: str
    prior: NDArray[np.float64]
    x: NDArray[np.float64]
    covariance_white: NDArray[np.float64]
    information: NDArray[np.float64]
    filter_residuals: list[StepResiduals] | None = None
    history: FilterHistory | None = None


@dataclass
class Uncertainty:
    """The combined covariance (white ⊕ bias instability on the actual geometry) and what is identifiable."""

    covariance: NDArray[np.float64]
    plan: IdentificationPlan
    rank: int
    condition: float
    unidentifiable: set[str]
    time_covariance: NDArray[np.float64] | None = None  # J Σ Jᵀ of the time base (included in ``covariance``)
    time_sensitivity: NDArray[np.float64] | None = None  # J = ∂x/∂(t₀, ε), (18, 2)


def measurement_noise(data: IdentificationData, noise: str) -> NDArray[np.float64]:
    """Per-sample white-noise variance per axis (SI²): from the bench ("configured") or the warm-up."""
    if noise == "configured":
        return configured_noise_variance(data.config, data.model)
    if noise == "warm-up":
        if data.warmup_accel is None or data.warmup_accel.shape[0] < 100:
            raise IdentificationError(f"{data.path}: no warm-up record to estimate R from; use --noise configured")
        warm = data.warmup_accel
        if data.model.n_axes == 6:
            assert data.warmup_gyro is not None
            warm = np.hstack([warm, data.warmup_gyro])
        return estimate_measurement_noise(warm)
    raise IdentificationError(f"unknown noise source {noise!r}; use configured or warm-up")


def estimate(data: IdentificationData, method: str, noise: str = "configured") -> Estimate:
    """Run the estimator (streaming Kalman filter over the windows in order, or batch least squares)."""
    model = data.model
    p0 = prior_covariance(data.config, model)
    r_var = measurement_noise(data, noise)
    if method == "kalman":
        kf = StreamingIdentifier(r_var, p0, sample_rate=data.config.unit.sample_rate, model=model)
        for w in data.windows:
            kf.update(w.output_columns(model), w.f_ref, w.omega, w.name, t=w.t, earth=w.earth)
        rows = [
            StepResiduals(name=name, samples=int(st.count), mean=list(map(float, st.mean)),
                          rms=list(map(float, st.rms)))
            for name, st in kf.residual_statistics().items()
        ]  # fmt: skip
        history = FilterHistory(
            time=[h.time for h in kf.history],
            step=[h.step for h in kf.history],
            estimate=[list(map(float, h.x)) for h in kf.history],
            sigma=[list(map(float, h.sigma)) for h in kf.history],
        )
        return Estimate(method, r_var, noise, p0, kf.estimate, kf.covariance, kf.information, rows, history)
    if method == "batch":
        ws = data.windows
        earth = None if model.n_axes == 3 else np.concatenate([w.earth for w in ws])  # type: ignore[misc]
        res = batch_identify(
            np.concatenate([w.output(model) for w in ws]), np.concatenate([w.f_ref for w in ws]),
            np.concatenate([w.omega for w in ws]), r_var, None, p0, model=model, earth=earth,
        )  # fmt: skip
        return Estimate(method, r_var, noise, p0, res.x, res.covariance, res.information)
    raise IdentificationError(f"unknown method {method!r}; use kalman or batch")


def residual_statistics(data: IdentificationData, est: Estimate) -> Residuals:
    """Per-step residual mean and RMS per body axis (m/s²) and the overall RMS (sample-weighted)."""
    rows = est.filter_residuals
    if rows is None:
        rows = []
        for w in data.windows:
            r = w.output(data.model) - data.model.predict(est.x, w.f_ref, w.omega, w.earth)
            rows.append(
                StepResiduals(name=w.name, samples=int(r.shape[0]), mean=list(map(float, r.mean(0))),
                              rms=list(map(float, np.sqrt((r**2).mean(0)))))
            )  # fmt: skip
    kinds = {w.name: w.kind for w in data.windows}
    rows = [dataclasses.replace(r, kind=kinds.get(str(r.name), "")) for r in rows]
    n_s = np.array([r.samples for r in rows], dtype=float)
    ms_s = np.array([r.rms for r in rows]) ** 2
    rms_all = np.sqrt((n_s[:, None] * ms_s).sum(0) / n_s.sum())
    return Residuals(rms=list(map(float, rms_all)), per_step=tuple(rows))


def combined_uncertainty(data: IdentificationData, est: Estimate) -> Uncertainty:
    """White covariance ⊕ the bias instability's systematic term, on the actual data geometry; rank."""
    model = data.model
    b = bias_stability(data.config, model)
    actual = plan_identification(
        _windows_as_plan_steps(data.windows),
        est.noise_variance,
        est.prior,
        b,
        offset_covariance=offset_covariance([(float(w.t[0]), float(w.t[-1])) for w in data.windows], b),
        model=model,
    )
    p_time, jac = _time_base_covariance(data, est.noise_variance, est.prior)
    p_total = est.covariance_white + (actual.covariance_total - actual.covariance_white) + p_time
    p_total = 0.5 * (p_total + p_total.T)
    rank, cond = information_rank(est.information, est.noise_variance, model=model)
    unobs = set(unobservable_parameters(est.information, est.noise_variance, model=model)) | set(actual.unidentifiable)
    return Uncertainty(p_total, actual, int(rank), float(cond), unobs, p_time, jac)


def _time_base_covariance(
    data: IdentificationData, r_var: NDArray[np.float64], p0: NDArray[np.float64]
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The identified parameters' covariance from the time base's uncertainty, J Σ Jᵀ, and J = ∂x/∂(t₀, ε) (n, 2).

    The accelerometer rows are the time-base analysis's sensitivities; the gyro's scale factors take ε 1 : 1
    (their rate reference is the encoder angle over the unit's time rescaled by 1 + ε, so δS_g = −δε), the
    other gyro rows are 0 (the offset only turns the Earth rate during spins, well below their u). The reference
    second's own u (the controller clock's rate against the host's, which rescales the same reference) is added
    to the gyro scale factors (benches.timebase.reference_rate_covariance).
    """
    tb = data.time_base
    cov = np.asarray(tb.covariance, dtype=float)
    n = data.model.n_params
    if data.table is None or not np.all(np.isfinite(cov)) or not np.any(cov):
        return np.zeros((n, n)), np.zeros((n, 2))
    cfg = data.config
    lat = unit_latency(cfg)
    fs = float(cfg.unit.sample_rate)
    wins = [(w.t, w.f_out, acquisition_span(float(w.t[0]), float(w.t[-1]), lat, fs)) for w in data.windows]
    jac = np.zeros((n, 2))
    jac[:18] = time_base_sensitivity(
        wins, data.table, g=cfg.site.g, mounting=cfg.unit.mounting, latency=lat, r_var=r_var[:3], p0=p0[:18, :18]
    )
    for a in ("x", "y", "z"):
        if f"gyro_S_{a}" in data.model.names:
            jac[data.model.index(f"gyro_S_{a}"), 1] = -1.0
    return jac @ cov @ jac.T + reference_rate_covariance(list(data.model.names), tb.check), jac


def _max_norm(v: NDArray[np.float64]) -> float:
    """``max(np.linalg.norm(v, axis=1))`` of an (n, 3) array, bit for bit: √ of the largest (v_x² + v_y²) + v_z²
    (the row sum's additions in numpy's order; √ is correctly rounded and monotonic, so it commutes with max),
    column by column instead of three values at a time."""
    v2 = v**2
    return float(np.sqrt(np.max((v2[:, 0] + v2[:, 1]) + v2[:, 2])))


def _time_base_warnings(data: IdentificationData) -> list[str]:
    """Lines for calibration.json's warnings: a timing misfit beyond what the budget carries (naming its cause),
    a host-clock check that disagrees, a time base that could not be measured.

    Within a motion the budget carries a reading's timing error up to the table's attitude accuracy (its
    rectangular u) over the fastest rate of the identified steps (a reference evaluated at rest does not depend
    on time; analysis.timebase.misfit_cause)."""
    tb = data.time_base
    out = [n for n in tb.notes if "disagrees" in n or "without a stated uncertainty" in n]
    host = tb.check.get("table_stamped_by") == "host"
    w_max = max((_max_norm(w.omega) for w in data.windows if w.omega.size), default=0.0)
    att = float(data.config.turntable.attitude_accuracy) / math.sqrt(3.0)
    cause = misfit_cause(tb, host_stamped=host, carried=att / w_max if w_max > 0 else math.inf)
    if cause:
        out.append(cause)
    return out


def _time_base_block(data: IdentificationData, unc: Uncertainty) -> TimeBaseBlock:
    """calibration.json's ``time_base``: the estimate, its u, the method, its effect on each parameter (u, SI,
    included in the covariance; sensitivities) and on a gyro scale factor (ε 1:1)."""
    d = data.time_base.as_dict()
    for k in ("u_offset_s", "u_rate", "misfit"):
        if not math.isfinite(d[k]):
            d[k] = None
    d["covariance"] = [[x if math.isfinite(x) else None for x in row] for row in d["covariance"]]
    n = data.model.n_params
    p_time = unc.time_covariance if unc.time_covariance is not None else np.zeros((n, n))
    jac = unc.time_sensitivity if unc.time_sensitivity is not None else np.zeros((n, 2))
    d["effect_u"] = {nm: float(math.sqrt(max(p_time[k, k], 0.0))) for k, nm in enumerate(data.model.names)}
    d["sensitivity"] = {nm: [float(jac[k, 0]), float(jac[k, 1])] for k, nm in enumerate(data.model.names)}
    d["gyro_scale_factor_u"] = d["u_rate"]  # a gyro scale factor measured as angle over time inherits ε 1:1
    return TimeBaseBlock.from_mapping(d)


def truth_check(
    truth: dict[str, float] | None, x: NDArray[np.float64], unc: Uncertainty, model: ModelSpec = ACCEL_MODEL
) -> TruthCheck | None:
    """Errors against a simulated bench's truth: error/u per parameter it states, NEES over the identified ones."""
    if not truth:
        return None
    names = model.names
    sigma = np.sqrt(np.diag(unc.covariance))
    have = [k for k, n_ in enumerate(names) if n_ in truth]
    err = {k: x[k] - truth[names[k]] for k in have}
    idx = np.array([k for k in have if names[k] not in unc.unidentifiable], dtype=int)
    e = np.array([err[k] for k in idx])
    sub = unc.covariance[np.ix_(idx, idx)]
    return TruthCheck(
        values={names[k]: float(truth[names[k]]) for k in have},
        error_over_u={names[k]: float(err[k] / sigma[k]) for k in have},
        nees=float(e @ np.linalg.solve(sub, e)) if idx.size else float("nan"),
        dof=int(idx.size),
        nees_states=[names[i] for i in idx],
    )


def _run_info(data: IdentificationData) -> RunInfo:
    a = data.run.attrs()
    config, temp = data.config, data.temperature
    temp = temp[np.isfinite(temp)]  # a unit without a temperature channel records NaN: no summary (None)
    return RunInfo(
        status=str(a.get("status", "")),
        bench_name=str(a.get("bench_name", "")),
        procedure_name=str(a.get("procedure_name", "")),
        procedure_sha256=str(a.get("procedure_sha256", "")),
        procedure_overrides=dict(a.get("procedure_overrides") or {}),
        integrity_verified=bool(a.get("integrity_verified", False)),
        integrity_note=str(a.get("integrity_note", "")),
        seed=-1 if a.get("seed") is None else int(a["seed"]),
        created_utc=str(a.get("created_utc", "")),
        transport=str(a.get("transport", "")),
        site={
            "name": config.site.name,
            "latitude_deg": math.degrees(config.site.latitude),
            "height_m": config.site.height,
            "g": config.site.g,
            "g_source": config.site.g_source,
        },
        unit={"model": config.unit.model, "serial_number": config.unit.serial_number},
        table={
            "model": config.turntable.model,
            "serial_number": config.turntable.serial_number,
            "attitude_accuracy": config.turntable.attitude_accuracy,
        },
        temperature_k={
            "mean": float(temp.mean()) if temp.size else None,
            "min": float(temp.min()) if temp.size else None,
            "max": float(temp.max()) if temp.size else None,
        },
    )


def calibration_result(
    data: IdentificationData, est: Estimate, residuals: Residuals, unc: Uncertainty, truth: TruthCheck | None
) -> CalibrationResult:
    """Assemble the typed calibration result (refused when anything is non-finite: nothing is written)."""
    x, p_total, p_white = est.x, unc.covariance, est.covariance_white
    if not (np.all(np.isfinite(x)) and np.all(np.isfinite(p_total)) and np.all(np.isfinite(p_white))):
        raise IdentificationError(
            f"{data.path}: the identification produced non-finite estimates or covariance (damaged data?); "
            "nothing was written"
        )
    sigma, sigma_white = np.sqrt(np.diag(p_total)), np.sqrt(np.diag(p_white))
    model = data.model
    params = {
        name: ParameterEstimate(
            name=name,
            kind=model.kinds[k],
            value=float(x[k]),
            u=float(sigma[k]),
            u_white=float(sigma_white[k]),
            prior_sigma=float(math.sqrt(est.prior[k, k])),
            identified=name not in unc.unidentifiable,
        )
        for k, name in enumerate(model.names)
    }
    actual = unc.plan
    warnings = list(actual.warnings)
    dflt = defaulted_priors(data.config, model)
    if dflt:
        warnings.append(
            f"the bench file states no prior for {', '.join(dflt)}: tactical-grade defaults used "
            "(10 °/h, 1000 ppm, 100″, 1 °/h/g); give unit.prior gyro_* keys from the datasheet"
        )
    warnings += _time_base_warnings(data)
    if data.incomplete_steps:
        warnings.insert(0, f"recording incomplete: step(s) {', '.join(data.incomplete_steps)} not completed")
    if not data.run.integrity_verified:
        warnings.insert(0, data.run.integrity_note or "recording integrity cannot be verified")
    return CalibrationResult(
        parameters=params,
        covariance=np.array([list(map(float, row)) for row in p_total]),
        covariance_white=np.array([list(map(float, row)) for row in p_white]),
        noise_variance=np.array(list(map(float, est.noise_variance))),
        method=est.method,
        recording=data.path.name,
        recording_sha256=data.run.sha256,
        noise_source=est.noise_source,
        software_version=str(data.run.header.software_version or ""),
        model=model.equation,
        information=InformationSummary(
            rank=unc.rank,
            condition=unc.condition,
            unidentifiable=sorted(unc.unidentifiable, key=model.names.index),
            tolerance="numerical rank of the noise-whitened data information, scaled per parameter kind "
            "(analysis.identification.batch.information_rank)",
        ),
        residuals=residuals,
        plan=PlanSummary(
            predicted_sigma={n_: float(actual.sigma_total[k]) for k, n_ in enumerate(model.names)},
            rank=int(actual.rank),
            warnings=list(actual.warnings),
        ),
        truth=truth,
        history=est.history,
        run=_run_info(data),
        warnings=warnings,
        time_base=_time_base_block(data, unc),
    )


def identify_run(
    run: str | Path | RecordedRun,
    method: str = "kalman",
    noise: str = "configured",
    time_base: str = "estimate",
    *,
    with_gyro: bool | None = None,
) -> CalibrationResult:
    """Identify the unit's parameters from a recording; returns the typed calibration result.

    The model is the unit's (:func:`unit_model`): the accelerometer's 18 states, and the gyro's when the
    recording has gyro data (``with_gyro`` None) or when asked (True); False: the accelerometer alone.

    Parameters
    ----------
    run : path or RecordedRun
        Run folder, recording file, or an open :class:`RecordedRun` (``tablebench run`` passes its own).
    method : {"kalman", "batch"}
        The streaming filter over all windows in order, or batch least squares (same prior, same model).
    noise : {"configured", "warm-up"}
        R from the bench's configured VRW (and ARW), or estimated from the run's warm-up record.
    time_base : {"estimate", "none"}
        Map the table's clock to the unit's with the run's estimated time base (benches.timebase), or take
        them as one clock (what the live filter during the run does; for comparisons).
    """
    if method not in ("kalman", "batch"):
        raise IdentificationError(f"unknown method {method!r}; use kalman or batch")
    key = _data_key(run, time_base, with_gyro)
    with _opened(run) as rr:
        data = _identification_data(rr, time_base, with_gyro)
        _RECENT.clear()
        if key is not None and key == _data_key(rr, time_base, with_gyro):  # unchanged while it was read
            _RECENT.update(key=key, data=data)
        est = estimate(data, method, noise)
        residuals = residual_statistics(data, est)
        unc = combined_uncertainty(data, est)
        truth = truth_check(data.truth, est.x, unc, data.model)
        result = calibration_result(data, est, residuals, unc, truth)
    return CalibrationResult.from_dict(result.to_dict(), str(data.path))  # the checks every reader applies


def write_calibration(result: CalibrationResult, out: str | Path) -> Path:
    """Write ``calibration.json`` (strict: a non-finite number raises; :meth:`CalibrationResult.save`)."""
    return result.save(out)

"""Configuration of the simulated bench (truth of the table, the unit and the Earth), SI throughout.

A :class:`SimConfig` holds everything :class:`drivers.sim.world.SimulatedWorld` needs. It is normally
built by ``benches.bench_config.load_bench`` from a bench YAML file (display units there, converted once
through ``analysis.units``), but every field has a sensible default so tests can build one directly::

    SimConfig(accel=AccelTruth(bias=(1e-3, 0, 0)))

Frames: body frame b (the unit's case axes) for every sensor quantity; the mounting ``C_b^t`` rotates
body vectors into the inner-gimbal frame t; gimbal angles as in ``analysis.gimbal``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from analysis.earth import normal_gravity
from analysis.identification.model import PARAM_NAMES
from analysis.units import ARCSEC, DEG, DEG_PER_HOUR, DEG_PER_SQRT_HOUR, MM, PPM, UG, UG_PER_G2
from drivers.imu_unit.counts import CountScale
from drivers.protocols import AxisLimits, FaultCode
from drivers.sim.thermal_config import ChamberSim, ThermalTruth

Vec3 = tuple[float, float, float]
Mat3 = tuple[Vec3, Vec3, Vec3]

ACCEL_PARAM_NAMES: tuple[str, ...] = PARAM_NAMES
"""The 18 accelerometer-model parameters, in state order (docs/methods/accelerometer-calibration.md)."""

MISALIGNMENT_PAIRS: tuple[tuple[int, int], ...] = ((0, 1), (0, 2), (1, 0), (1, 2), (2, 0), (2, 1))
"""(i, j) of τ_xy τ_xz τ_yx τ_yz τ_zx τ_zy: δf_i += τ_ij f_j."""

CHANNELS: tuple[str, ...] = ("accel_x", "accel_y", "accel_z", "gyro_x", "gyro_y", "gyro_z")
"""Output channel names, in the order of the unit's count columns."""

_I3: Mat3 = ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0))
_Z3: Mat3 = ((0.0, 0.0, 0.0), (0.0, 0.0, 0.0), (0.0, 0.0, 0.0))


def _good_table_limits() -> tuple[AxisLimits, AxisLimits, AxisLimits]:
    lim = AxisLimits(rate_max=300.0 * DEG, accel_max=100.0 * DEG)
    return (lim, lim, lim)


@dataclass(frozen=True)
class AccelTruth:
    """True accelerometer-triad errors (docs/methods/accelerometer-calibration.md), SI, body frame.

    Attributes
    ----------
    bias : (3,) m/s².
    scale : (3,) scale-factor errors S_i (dimensionless).
    misalignment : (6,) τ_xy τ_xz τ_yx τ_yz τ_zx τ_zy, rad; δf_i += τ_ij f_j.
    quadratic : (3,) d_i, s²/m; δf_i += d_i f_i².
    lever_arms : (3, 3) row i = ρ_i, position of accelerometer i relative to the table's rotation centre,
        m, body frame. The 3-parameter model's size effect is r_i = −ρ_{i,i}.
    """

    bias: Vec3 = (0.0, 0.0, 0.0)
    scale: Vec3 = (0.0, 0.0, 0.0)
    misalignment: tuple[float, float, float, float, float, float] = (0.0,) * 6
    quadratic: Vec3 = (0.0, 0.0, 0.0)
    lever_arms: Mat3 = _Z3


@dataclass(frozen=True)
class GyroTruth:
    """True gyro-triad errors, SI, body frame.

    Attributes
    ----------
    bias : (3,) rad/s.
    scale : (3,) scale-factor errors (dimensionless).
    misalignment : (6,) τ_xy τ_xz τ_yx τ_yz τ_zx τ_zy, rad; δω_i += τ_ij ω_j (same convention as accel).
    g_sensitivity : (3, 3) rad/s per m/s²; δω = G f (f the specific force at the reference point).
    quadratic : (3,) s/rad; δω_i += S2_i ω_i² (the scale factor's second-order nonlinearity).
    asymmetry : (3,) dimensionless; δω_i += A_i |ω_i| (scale factor 1 + S ± A for ± rates).
    """

    bias: Vec3 = (0.0, 0.0, 0.0)
    scale: Vec3 = (0.0, 0.0, 0.0)
    misalignment: tuple[float, float, float, float, float, float] = (0.0,) * 6
    g_sensitivity: Mat3 = _Z3
    quadratic: Vec3 = (0.0, 0.0, 0.0)
    asymmetry: Vec3 = (0.0, 0.0, 0.0)


def gyro_truth(gyro: GyroTruth) -> dict[str, float]:
    """The gyro model's parameters by name (``gyro_b_x`` …, SI) for a simulated gyro truth."""
    ax = "xyz"
    others = ((1, 2), (0, 2), (0, 1))
    g = np.asarray(gyro.g_sensitivity, dtype=float)
    out = {f"gyro_b_{ax[i]}": float(gyro.bias[i]) for i in range(3)}
    out |= {f"gyro_S_{ax[i]}": float(gyro.scale[i]) for i in range(3)}
    tau = [f"gyro_tau_{ax[i]}{ax[j]}" for i in range(3) for j in others[i]]
    out |= {n: float(v) for n, v in zip(tau, gyro.misalignment, strict=True)}
    out |= {f"gyro_G_{ax[i]}{ax[i]}": float(g[i, i]) for i in range(3)}
    out |= {f"gyro_G_{ax[i]}{ax[j]}": float(g[i, j]) for i in range(3) for j in others[i]}
    s2 = getattr(gyro, "quadratic", None)
    asym = getattr(gyro, "asymmetry", None)
    if s2 is not None and any(s2):
        out |= {f"gyro_S2_{ax[i]}": float(s2[i]) for i in range(3)}
    if asym is not None and any(asym):
        out |= {f"gyro_A_{ax[i]}": float(asym[i]) for i in range(3)}
    return out


@dataclass(frozen=True)
class NoiseTruth:
    """Stochastic errors of one triad (IEEE 952 / IEEE 1293 conventions), SI per channel.

    Attributes
    ----------
    white : (3,) white-noise density N: Allan deviation N/√τ, per-sample std N·√f_s
        (accel: m/s²/√Hz = m/s/√s, velocity random walk; gyro: rad/√s, angle random walk).
    bias_instability : (3,) B: flicker floor of the Allan deviation ≈ 0.664 B (accel m/s², gyro rad/s).
        Realised as a sum of first-order Gauss–Markov processes, two per decade over ``flicker_band``.
    random_walk : (3,) K: rate / acceleration random walk, Allan deviation K√(τ/3) (unit/s·√s = unit/√s).
    flicker_band : (f_low, f_high) Hz, corner-frequency band of the flicker approximation.
    """

    white: Vec3 = (0.0, 0.0, 0.0)
    bias_instability: Vec3 = (0.0, 0.0, 0.0)
    random_walk: Vec3 = (0.0, 0.0, 0.0)
    flicker_band: tuple[float, float] = (1e-4, 1.0)


@dataclass(frozen=True)
class TemperatureModel:
    """Unit temperature and its effect on bias and scale (linear in the deviation from settled).

    T(t) = ambient + warmup_rise·(1 − exp(−t/warmup_tau)), °C. Errors drift by coefficient × (T − T_settled)
    with T_settled = ambient + warmup_rise, so after warm-up the configured truth holds.

    Attributes
    ----------
    ambient_c, warmup_rise_c : °C.
    warmup_tau : s.
    accel_bias_tc : (3,) m/s² per K.  accel_scale_tc : (3,) 1/K.
    gyro_bias_tc : (3,) rad/s per K.  gyro_scale_tc : (3,) 1/K.
    """

    ambient_c: float = 23.0
    warmup_rise_c: float = 0.0
    warmup_tau: float = 600.0
    accel_bias_tc: Vec3 = (0.0, 0.0, 0.0)
    accel_scale_tc: Vec3 = (0.0, 0.0, 0.0)
    gyro_bias_tc: Vec3 = (0.0, 0.0, 0.0)
    gyro_scale_tc: Vec3 = (0.0, 0.0, 0.0)


@dataclass(frozen=True)
class PeriodicTerm:
    """A periodic error A cos(2π f t + φ) added to one output channel (docs/methods/periodic.md).

    Attributes
    ----------
    channel : one of ``CHANNELS``.
    frequency_hz : Hz.
    amplitude : SI (m/s² or rad/s).
    phase : rad.
    """

    channel: str
    frequency_hz: float
    amplitude: float
    phase: float = 0.0


@dataclass(frozen=True)
class ArmaDrift:
    """ARMA-coloured drift on one channel (docs/methods/drift.md sign convention), per output sample.

    x_t − Σ φ_j x_{t−j} = e_t − Σ θ_j e_{t−j},  e_t ~ N(0, σ²) white at the sample rate.

    Attributes
    ----------
    channel : one of ``CHANNELS``.
    phi, theta : AR and MA coefficients.
    sigma : std of the driving white noise e, SI (m/s² or rad/s).
    """

    channel: str
    phi: tuple[float, ...] = ()
    theta: tuple[float, ...] = ()
    sigma: float = 0.0


@dataclass(frozen=True)
class TableModel:
    """Turntable behaviour and imperfections.

    Attributes
    ----------
    limits : per-axis (outer, middle, inner) rate/accel/position limits.
    position_tolerance : rad, in-position window.
    in_position_time : s, time inside the window before IN_POSITION is set.
    watchdog : s of bench time without heartbeat while moving before the table is stopped (None: off).
    slew_fraction : fraction of rate_max a position move cruises at.
    overshoot : rad, amplitude of the settling transient A·exp(−τ/τ_s)·sin(2π f_s τ) after a move.
    settle_frequency_hz, settle_time_constant : f_s (Hz) and τ_s (s) of that transient.
    encoder_bits : reported angles are quantised to 2π / 2^bits.
    position_jitter : rad, white noise std of the reported angles.
    rate_jitter : rad/s, std of the physical rate jitter (first-order Gauss–Markov per axis).
    rate_jitter_tau : s, correlation time of the rate jitter.
    non_orthogonality : (2,) rad: tilt of the middle axis w.r.t. the outer (about outer y) and of the inner
        axis w.r.t. the middle (about middle z). Zero by default.
    wobble : rad, inner-axis wobble: the inner gimbal is tilted by ``wobble`` about an axis that turns once
        per inner revolution, C_t^m = E2 R_x(w cos γ) R_z(w sin γ) R_y(γ). Zero by default.
    """

    limits: tuple[AxisLimits, AxisLimits, AxisLimits] = field(default_factory=_good_table_limits)
    position_tolerance: float = 2.0 * ARCSEC
    in_position_time: float = 0.2
    watchdog: float | None = 2.0
    slew_fraction: float = 0.9
    overshoot: float = 5.0 * ARCSEC
    settle_frequency_hz: float = 4.0
    settle_time_constant: float = 0.08
    encoder_bits: int = 24
    position_jitter: float = 0.1 * ARCSEC
    rate_jitter: float = 1e-4 * DEG
    rate_jitter_tau: float = 0.05
    non_orthogonality: tuple[float, float] = (0.0, 0.0)
    wobble: float = 0.0


@dataclass(frozen=True)
class ScheduledFault:
    """A fault the simulator injects by itself at bench time ``time`` (s)."""

    time: float
    fault: FaultCode


@dataclass(frozen=True)
class BudgetInputs:
    """Type-B inputs of the certificate's uncertainty budget that the simulator realises (seeded draws).

    A real bench has them whether we like it or not; the simulated bench draws them so that the budget's
    coverage can be measured (benchmarks/bench_calibration.py). Each is drawn from the distribution the
    budget assumes, from its own random stream (the other streams do not change).

    Attributes
    ----------
    gravity_anomaly_std : m/s². True local g = the bench's g + δg, δg ~ N(0, u(g)²), once per run.
    attitude_error_bound : rad. Every motion command (position or rate) leaves the table at a true attitude
        C_b^n,true = (I + [δφ×]) C_b^n,reported, δφ uniform in ±bound per navigation axis, until the next one.
    rate_error_bound : relative. Gimbal axis j turns at (1 + ε_j) × its commanded rate, ε_j uniform in ±bound,
        once per run and axis; its encoder reports the true angles and its reported rate is the measured rate
        of that motion (a real table's rate error: docs/methods/simulation.md).
    azimuth_std : rad. The outer gimbal's zero is off East by δψ ~ N(0, std²), once per run: the true
        C_b^n = R_z(δψ) C_b^n,reported (the Earth rate is seen in the true frame; gravity is vertical either way).
    axis_tilt_bound : rad. The table's axis non-orthogonality: the middle axis tilted by ε₁ (about the outer
        frame's y) and the inner axis by ε₂ (about the middle frame's z), each uniform in ±bound, once per run,
        added to ``TableModel.non_orthogonality`` (``analysis.identification.table_axes``).
    latitude_std : rad. The site's true latitude is the bench's + δφ, δφ ~ N(0, std²), once per run (the Earth
        rate the unit senses).
    """

    gravity_anomaly_std: float = 0.0
    attitude_error_bound: float = 0.0
    rate_error_bound: float = 0.0
    azimuth_std: float = 0.0
    axis_tilt_bound: float = 0.0
    latitude_std: float = 0.0


@dataclass(frozen=True)
class ClockModel:
    """The bench's clocks (docs/methods/time-base.md): the unit's oscillator, the controller's clock, the host's
    arrival times.

    ``mode`` "ideal": one clock drives table and unit (the unit's sample clock is true time, the controller
    reports it, nothing is late). "separate": each run draws (seeded, uniform within the stated bounds) the
    unit's oscillator error ε_u and the controller clock's rate error ε_c and offset c₀; the unit's frames reach
    the host in batches of ``batch_frames`` after a transport latency with jitter; every controller transaction
    (a reading, a command) is latched ``reading_latency`` (+ jitter) after the host sends it and answered
    ``answer_latency`` (+ jitter) later. Jitters are exponential with the given mean (latency only grows).

    Physics: the true time of unit sample k is τ_k = k / (f_s (1 + ε_u)); the controller's clock reads
    c = c₀ + (1 + ε_c) τ; the host's clock is true time τ. So a table time stamped by the controller maps to the
    unit's sample time t_u = k / f_s by t_table = c₀ + (1 + ε) t_u with 1 + ε = (1 + ε_c)/(1 + ε_u).

    Attributes
    ----------
    mode : "ideal" or "separate".
    unit_rate_bound : relative; ε_u uniform in ±bound (a MEMS unit 20–100 ppm).
    controller_rate_bound : relative; ε_c uniform in ±bound.
    controller_offset_bound : s; c₀ uniform in ±bound.
    link_latency, link_jitter : s; unit → host transport latency and the mean of its exponential jitter.
    batch_frames : frames the link delivers at once (serial buffering, a device server).
    reading_latency, reading_jitter : s; host request → controller latch.
    answer_latency, answer_jitter : s; controller latch → host receives the answer.
    unit_rate : relative or None; the unit's oscillator error exactly (None: drawn within ±unit_rate_bound).
    """

    mode: str = "ideal"
    unit_rate_bound: float = 50e-6
    controller_rate_bound: float = 10e-6
    controller_offset_bound: float = 0.020
    link_latency: float = 0.002
    link_jitter: float = 0.0005
    batch_frames: int = 8
    reading_latency: float = 0.001
    reading_jitter: float = 0.0003
    answer_latency: float = 0.001
    answer_jitter: float = 0.0003
    unit_rate: float | None = None

    @property
    def separate(self) -> bool:
        """True when the bench has separate clocks."""
        return self.mode == "separate"


@dataclass(frozen=True)
class SimConfig:
    """Everything the simulated world needs, SI.

    Attributes
    ----------
    latitude : rad; height : m; g : local gravity magnitude used as physics truth, m/s².
    sample_rate : Hz; scale : count scale of the unit; mounting : (3, 3) C_b^t.
    accel, gyro : true triad errors. accel_noise, gyro_noise : stochastic errors.
    temperature : TemperatureModel or None (constant 23 °C, no drift).
    periodic : periodic terms. arma : ARMA drifts.
    anti_alias_hz : cutoff of the unit's 2nd-order Butterworth anti-alias filter applied to the physical
        signal (None or 0: off); noise, periodic and ARMA terms are specified at the output.
    timestamp_jitter : s, white std of the unit's time stamps.
    drop_probability : probability that a frame is lost (its counter value is skipped).
    table : TableModel. faults : scheduled faults.
    seed : default seed. transport : "in-process" or "loopback".
    clocks : ClockModel (the dataclass default is one ideal clock; a bench file's default is separate clocks).
    realtime : loopback only: the unit streams from its own thread in real time at its own clock's rate, in
        batches (``clocks.batch_frames``); the drivers use the host's real clock (not deterministic).
    chamber : ChamberSim or None — a simulated temperature chamber around the unit (its temperature then
        follows the chamber; ``temperature`` is ignored). thermal : ThermalTruth or None — the unit's errors
        as functions of its own temperature (:mod:`drivers.sim.thermal_config`).
    """

    latitude: float = 48.0 * DEG
    height: float = 300.0
    g: float | None = None
    sample_rate: float = 1000.0
    scale: CountScale = field(default_factory=lambda: CountScale(accel_lsb=0.1 * UG, gyro_lsb=1e-3 * DEG_PER_HOUR))
    mounting: Mat3 = _I3
    accel: AccelTruth = field(default_factory=AccelTruth)
    gyro: GyroTruth = field(default_factory=GyroTruth)
    accel_noise: NoiseTruth = field(default_factory=NoiseTruth)
    gyro_noise: NoiseTruth = field(default_factory=NoiseTruth)
    temperature: TemperatureModel | None = None
    periodic: tuple[PeriodicTerm, ...] = ()
    arma: tuple[ArmaDrift, ...] = ()
    anti_alias_hz: float | None = None
    timestamp_jitter: float = 0.0
    drop_probability: float = 0.0
    table: TableModel = field(default_factory=TableModel)
    faults: tuple[ScheduledFault, ...] = ()
    seed: int = 0
    transport: str = "in-process"
    budget_inputs: BudgetInputs | None = None
    clocks: ClockModel = field(default_factory=ClockModel)
    realtime: bool = False
    chamber: ChamberSim | None = None
    thermal: ThermalTruth | None = None

    @property
    def local_g(self) -> float:
        """Local gravity used by the physics, m/s²: ``g`` if given, else WGS-84 normal gravity at the site."""
        return float(self.g) if self.g is not None else normal_gravity(self.latitude, self.height)


def example_navigation_grade() -> SimConfig:
    """A navigation-grade quartz accelerometer triad + tactical gyro triad on a good table (tests, demos)."""
    return SimConfig(
        accel=AccelTruth(
            bias=(100 * UG, -80 * UG, 120 * UG),
            scale=(200 * PPM, -150 * PPM, 250 * PPM),
            misalignment=tuple(a * ARCSEC for a in (30.0, -25.0, 20.0, 35.0, -30.0, 15.0)),  # type: ignore[arg-type]
            quadratic=(20 * UG_PER_G2, -15 * UG_PER_G2, 25 * UG_PER_G2),
            lever_arms=((30 * MM, 5 * MM, -3 * MM), (4 * MM, -28 * MM, 6 * MM), (-5 * MM, 2 * MM, 32 * MM)),
        ),
        gyro=GyroTruth(bias=(0.5 * DEG_PER_HOUR, -0.3 * DEG_PER_HOUR, 0.4 * DEG_PER_HOUR), scale=(50e-6,) * 3),
        accel_noise=NoiseTruth(white=(15 * UG,) * 3, bias_instability=(3 * UG,) * 3),
        gyro_noise=NoiseTruth(white=(0.005 * DEG_PER_SQRT_HOUR,) * 3, bias_instability=(0.02 * DEG_PER_HOUR,) * 3),
    )


__all__ = [
    "ACCEL_PARAM_NAMES",
    "gyro_truth",
    "CHANNELS",
    "MISALIGNMENT_PAIRS",
    "AccelTruth",
    "ArmaDrift",
    "BudgetInputs",
    "ClockModel",
    "GyroTruth",
    "NoiseTruth",
    "PeriodicTerm",
    "ScheduledFault",
    "SimConfig",
    "TableModel",
    "TemperatureModel",
    "example_navigation_grade",
]

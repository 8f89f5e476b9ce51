"""The ``simulation:`` section of a bench file, parsed by the simulator that owns it (SI out).

:func:`parse_simulation` turns the section (display units: µg, ppm, arcsec, °/h, ...) into a
:class:`~drivers.sim.config.SimConfig`; :mod:`benches.bench_config` calls it with the bench's site, table
and unit, which it reads only through the small protocols below (so the simulator does not import
``benches``). Errors are :class:`~core.yaml_source.ConfigError` naming file:line and the key path.
"""

from __future__ import annotations

from typing import Any, Protocol

import numpy as np

from analysis.earth import DEFAULT_LATITUDE_U
from analysis.units import (
    ARCSEC,
    DEG,
    DEG_PER_HOUR,
    DEG_PER_HOUR_PER_SQRT_HOUR,
    DEG_PER_SQRT_HOUR,
    G0,
    MM,
    PPM,
    UG,
    UG_PER_G2,
    UG_PER_SQRT_HZ,
    UG_PER_SQRT_S,
)
from core.declare import Section, components, integer, matrix, number, text
from core.seeds import MAX_SEED
from core.yaml_source import (
    KeyPath,
    SourceMap,
    check_keys,
    get_number,
    get_str,
    get_vector,
)
from core.yaml_source import get_int as _int
from core.yaml_source import get_list_of_maps as _list_of_maps
from core.yaml_source import get_section as _section
from drivers.imu_unit.counts import CountScale
from drivers.protocols import AxisLimits, FaultCode
from drivers.sim.config import (
    CHANNELS,
    AccelTruth,
    ArmaDrift,
    BudgetInputs,
    ClockModel,
    GyroTruth,
    NoiseTruth,
    PeriodicTerm,
    ScheduledFault,
    SimConfig,
    TableModel,
    TemperatureModel,
)
from drivers.sim.thermal_section import parse_thermal

RATE_RW = DEG_PER_HOUR_PER_SQRT_HOUR  # 1 °/h/√h in rad/s/√s
DPH_PER_G = DEG_PER_HOUR / G0  # 1 °/h per g in rad/s per m/s²


class Site(Protocol):
    """Where the bench stands: latitude (rad), height (m), measured local g (m/s² or None)."""

    latitude: float
    height: float
    g_measured: float | None

    @property
    def g_uncertainty(self) -> float:
        """Standard uncertainty of the local g, m/s²."""


class Table(Protocol):
    """The bench's table as the simulated controller needs it (SI)."""

    limits: tuple[AxisLimits, AxisLimits, AxisLimits]
    position_tolerance: float
    in_position_time: float
    watchdog: float | None
    attitude_accuracy: float
    rate_accuracy: float
    azimuth_uncertainty: float | None


class UnitNoise(Protocol):
    """The unit's configured noise, SI per body axis."""

    vrw: np.ndarray
    bias_instability: np.ndarray
    arw: np.ndarray
    gyro_bias_instability: np.ndarray


class Unit(Protocol):
    """The bench's unit as the simulated unit needs it (SI)."""

    sample_rate: float
    scale: CountScale
    mounting: np.ndarray
    noise: UnitNoise


def _channel_unit(ch: str, smap: SourceMap, p: KeyPath, d: dict, stem: str) -> tuple[str, float]:
    """The amplitude/sigma key present for a channel and its SI factor (accel: µg; gyro: °/h or °/s)."""
    options = {"ug": UG} if ch.startswith("accel") else {"dph": DEG_PER_HOUR, "dps": DEG}
    present = [f"{stem}_{u}" for u in options if f"{stem}_{u}" in d]
    if len(present) != 1:
        allowed = " or ".join(f"{stem}_{u}" for u in options)
        raise smap.error(p, f"give exactly one of {allowed} for channel {ch!r}")
    return present[0], options[present[0].rsplit("_", 1)[1]]


Z3 = (0.0, 0.0, 0.0)

ACCEL_TRUTH = Section(
    components("bias_ug", UG, Z3, attr="bias"),
    components("scale_ppm", PPM, Z3, attr="scale"),
    components("misalignment_arcsec", ARCSEC, (0.0,) * 6, length=6, attr="misalignment"),
    components("quadratic_ug_g2", UG_PER_G2, Z3, attr="quadratic"),
    matrix("lever_arm_mm", MM, (Z3, Z3, Z3), attr="lever_arms"),
)
"""``simulation.accelerometer``: the accelerometer triad's truth (:class:`~drivers.sim.config.AccelTruth`)."""

GYRO_TRUTH = Section(
    components("bias_dph", DEG_PER_HOUR, Z3, attr="bias"),
    components("scale_ppm", PPM, Z3, attr="scale"),
    components("misalignment_arcsec", ARCSEC, (0.0,) * 6, length=6, attr="misalignment"),
    matrix("g_sensitivity_dph_per_g", DPH_PER_G, (Z3, Z3, Z3), attr="g_sensitivity"),
    components("quadratic_ppm_per_dps", PPM / DEG, Z3, attr="quadratic"),
    components("asymmetry_ppm", PPM, Z3, attr="asymmetry"),
)
"""``simulation.gyro``: the gyro triad's truth (:class:`~drivers.sim.config.GyroTruth`)."""

ACCEL_NOISE = Section(
    components("vrw_ug_per_sqrt_hz", UG_PER_SQRT_HZ, minimum=0, attr="white"),
    components("bias_instability_ug", UG, minimum=0, attr="bias_instability"),
    components("random_walk_ug_per_sqrt_s", UG_PER_SQRT_S, Z3, minimum=0, attr="random_walk"),
    extra=("flicker_band_hz",),
)
"""``simulation.accel_noise`` (defaults: the unit's configured noise)."""

GYRO_NOISE = Section(
    components("arw_deg_per_sqrt_h", DEG_PER_SQRT_HOUR, minimum=0, attr="white"),
    components("bias_instability_dph", DEG_PER_HOUR, minimum=0, attr="bias_instability"),
    components("rate_random_walk_dph_per_sqrt_h", RATE_RW, Z3, minimum=0, attr="random_walk"),
    extra=("flicker_band_hz",),
)
"""``simulation.gyro_noise`` (defaults: the unit's configured noise)."""

TEMPERATURE = Section(
    number("ambient_c", 23.0, minimum=-60, maximum=120),
    number("warmup_rise_c", 0.0, minimum=-50, maximum=100),
    number("warmup_tau_s", 600.0, minimum=0, exclusive_minimum=True, attr="warmup_tau"),
    components("accel_bias_ug_per_c", UG, Z3, attr="accel_bias_tc"),
    components("accel_scale_ppm_per_c", PPM, Z3, attr="accel_scale_tc"),
    components("gyro_bias_dph_per_c", DEG_PER_HOUR, Z3, attr="gyro_bias_tc"),
    components("gyro_scale_ppm_per_c", PPM, Z3, attr="gyro_scale_tc"),
)
"""``simulation.temperature``: the unit's temperature and its thermal sensitivities."""

TABLE_MODEL = Section(
    integer("encoder_bits", 24, 0, 40),
    number("position_jitter_arcsec", 0.1 * ARCSEC, unit=ARCSEC, minimum=0, attr="position_jitter"),
    number("rate_jitter_dps", 1e-4 * DEG, unit=DEG, minimum=0, attr="rate_jitter"),
    number("rate_jitter_tau_s", 0.05, minimum=0, exclusive_minimum=True, attr="rate_jitter_tau"),
    number("overshoot_arcsec", 5.0 * ARCSEC, unit=ARCSEC, minimum=0, attr="overshoot"),
    number("settle_frequency_hz", 4.0, minimum=0, exclusive_minimum=True),
    number("settle_time_constant_s", 0.08, minimum=0, exclusive_minimum=True, attr="settle_time_constant"),
    number("slew_fraction", 0.9, minimum=0, exclusive_minimum=True, maximum=1),
    components("non_orthogonality_arcsec", ARCSEC, (0.0, 0.0), length=2, attr="non_orthogonality"),
    number("wobble_arcsec", 0.0, unit=ARCSEC, minimum=0, maximum=3600, attr="wobble"),
)
"""``simulation.table``: the simulated table's imperfections (:class:`~drivers.sim.config.TableModel`)."""

SIMULATION = Section(
    integer("seed", 0, 0, MAX_SEED),
    text("transport", "in-process", choices=["in-process", "loopback"]),
    number("timestamp_jitter_us", 0.0, unit=1e-6, minimum=0, maximum=1e5, attr="timestamp_jitter"),
    number("drop_probability", 0.0, minimum=0, maximum=0.5),
    order=(
        "seed",
        "transport",
        "controller",
        "accelerometer",
        "gyro",
        "accel_noise",
        "gyro_noise",
        "temperature",
        "thermal",
        "periodic",
        "arma",
        "anti_alias_hz",
        "timestamp_jitter_us",
        "drop_probability",
        "table",
        "faults",
        "realise_uncertainty_inputs",
        "clocks",
        "realtime",
    ),
)
"""``simulation:`` itself; ``controller`` is read by the bench loader (the device registry)."""


def parse_simulation(d: dict, smap: SourceMap, site: Site, table: Table, unit: Unit) -> SimConfig:
    """Parse the bench file's ``simulation:`` mapping ``d`` into a :class:`SimConfig` (SI)."""
    p: KeyPath = ("simulation",)
    top = SIMULATION.read(d, smap, p)
    fs = unit.sample_rate
    accel = ACCEL_TRUTH.build(AccelTruth, _section(d, smap, p, "accelerometer", required=False), smap,
                              p + ("accelerometer",))  # fmt: skip
    gyro = GYRO_TRUTH.build(GyroTruth, _section(d, smap, p, "gyro", required=False), smap, p + ("gyro",))
    noise = unit.noise
    accel_noise = _noise(ACCEL_NOISE, d, smap, p, "accel_noise", fs, (noise.vrw, noise.bias_instability))
    gyro_noise = _noise(GYRO_NOISE, d, smap, p, "gyro_noise", fs, (noise.arw, noise.gyro_bias_instability))
    td = _section(d, smap, p, "temperature", required=False)
    temperature = None if td is None else TEMPERATURE.build(TemperatureModel, td, smap, p + ("temperature",))
    tm = TABLE_MODEL.build(
        TableModel,
        _section(d, smap, p, "table", required=False),
        smap,
        p + ("table",),
        limits=table.limits,
        position_tolerance=table.position_tolerance,
        in_position_time=table.in_position_time,
        watchdog=table.watchdog,
    )
    aa = get_number(d, smap, p, "anti_alias_hz", None, minimum=0)
    if aa is not None and aa >= fs / 2:
        raise smap.error(
            p + ("anti_alias_hz",), f"{aa:g} Hz must be below the Nyquist frequency {fs / 2:g} Hz (0: off)"
        )
    return SimConfig(
        latitude=site.latitude,
        height=site.height,
        g=site.g_measured,
        sample_rate=fs,
        scale=unit.scale,
        mounting=tuple(tuple(float(x) for x in row) for row in unit.mounting),  # type: ignore[arg-type]
        accel=accel,
        gyro=gyro,
        accel_noise=accel_noise,
        gyro_noise=gyro_noise,
        temperature=temperature,
        thermal=parse_thermal(d, smap, p),
        periodic=_periodic(d, smap, p, fs),
        arma=_arma(d, smap, p),
        anti_alias_hz=aa or None,
        table=tm,
        faults=_faults(d, smap, p),
        budget_inputs=_budget_inputs(d, smap, p, site, table),
        clocks=parse_clocks(d, smap, p),
        realtime=_realtime(d, smap, p),
        **top,
    )


def _noise(
    section: Section, d: dict, smap: SourceMap, p: KeyPath, key: str, fs: float, configured: tuple[Any, Any]
) -> NoiseTruth:
    """A noise section; white noise and bias instability default to the unit's configured values."""
    nd = _section(d, smap, p, key, required=False) or {}
    defaults = {"white": tuple(configured[0]), "bias_instability": tuple(configured[1])}
    return section.build(NoiseTruth, nd, smap, p + (key,), defaults, flicker_band=_band(nd, smap, p + (key,), fs))


def _periodic(d: dict, smap: SourceMap, p: KeyPath, fs: float) -> tuple[PeriodicTerm, ...]:
    """``simulation.periodic``: strong periodic terms per channel (the amplitude key names its unit)."""
    out = []
    for ip, item in _list_of_maps(d, smap, p, "periodic"):
        ch = get_str(item, smap, ip, "channel", choices=list(CHANNELS))
        key, si = _channel_unit(ch, smap, ip, item, "amplitude")
        check_keys(item, smap, ip, ["channel", "frequency_hz", key, "phase_deg"])
        out.append(
            PeriodicTerm(
                channel=ch,
                frequency_hz=get_number(
                    item, smap, ip, "frequency_hz", minimum=0, exclusive_minimum=True, maximum=fs / 2
                ),
                amplitude=get_number(item, smap, ip, key, minimum=0) * si,
                phase=get_number(item, smap, ip, "phase_deg", 0.0, minimum=-360, maximum=360) * DEG,
            )
        )
    return tuple(out)


def _arma(d: dict, smap: SourceMap, p: KeyPath) -> tuple[ArmaDrift, ...]:
    """``simulation.arma``: ARMA-coloured drift per channel (stationary AR part)."""
    out = []
    for ip, item in _list_of_maps(d, smap, p, "arma"):
        ch = get_str(item, smap, ip, "channel", choices=list(CHANNELS))
        key, si = _channel_unit(ch, smap, ip, item, "sigma")
        check_keys(item, smap, ip, ["channel", "phi", "theta", key])
        coef = {}
        for name in ("phi", "theta"):
            v = item.get(name, [])
            if isinstance(v, (int, float)) and not isinstance(v, bool):
                v = [v]
            if not isinstance(v, list) or len(v) > 5:
                raise smap.error(ip + (name,), f"expected a list of up to 5 numbers like [0.9], got {v!r}")
            coef[name] = tuple(get_vector({name: v}, smap, ip, name, len(v)))
        if coef["phi"] and np.any(np.abs(np.roots([1.0, *(-np.array(coef["phi"]))])) >= 1.0):
            raise smap.error(
                ip + ("phi",), f"AR part {list(coef['phi'])} is not stationary (roots must be inside the unit circle)"
            )
        out.append(
            ArmaDrift(
                channel=ch, phi=coef["phi"], theta=coef["theta"], sigma=get_number(item, smap, ip, key, minimum=0) * si
            )
        )
    return tuple(out)


def _faults(d: dict, smap: SourceMap, p: KeyPath) -> tuple[ScheduledFault, ...]:
    """``simulation.faults``: faults injected at bench times."""
    out = []
    for ip, item in _list_of_maps(d, smap, p, "faults"):
        check_keys(item, smap, ip, ["time_s", "fault"])
        names = [f.name for f in FaultCode if f != FaultCode.NONE]
        out.append(
            ScheduledFault(
                time=get_number(item, smap, ip, "time_s", minimum=0),
                fault=FaultCode[get_str(item, smap, ip, "fault", choices=names)],
            )
        )
    return tuple(out)


def _realtime(d: dict, smap: SourceMap, p: KeyPath) -> bool:
    v = d.get("realtime", False)
    if not isinstance(v, bool):
        raise smap.error(p + ("realtime",), f"expected true or false, got {v!r}")
    if v and d.get("transport", "in-process") != "loopback":
        raise smap.error(p + ("realtime",), "a real-time unit needs transport: loopback (it streams over a socket)")
    return v


CLOCK_KEYS: dict[str, tuple[str, float, float]] = {
    # key: (ClockModel field, SI factor, default in display units)
    "unit_rate_ppm": ("unit_rate_bound", PPM, 50.0),
    "controller_rate_ppm": ("controller_rate_bound", PPM, 10.0),
    "controller_offset_ms": ("controller_offset_bound", 1e-3, 20.0),
    "link_latency_ms": ("link_latency", 1e-3, 2.0),
    "link_jitter_ms": ("link_jitter", 1e-3, 0.5),
    "reading_latency_ms": ("reading_latency", 1e-3, 1.0),
    "reading_jitter_ms": ("reading_jitter", 1e-3, 0.3),
    "answer_latency_ms": ("answer_latency", 1e-3, 1.0),
    "answer_jitter_ms": ("answer_jitter", 1e-3, 0.3),
}


def parse_clocks(d: dict, smap: SourceMap, p: KeyPath) -> ClockModel:
    """``simulation.clocks``: ``ideal``, ``separate`` (the default, with the defaults of :data:`CLOCK_KEYS`), or a
    mapping ``{mode: separate, unit_rate_ppm: …, batch_frames: …}`` (BENCH_FORMAT.md)."""
    v = d.get("clocks", "separate")
    cp = p + ("clocks",)
    if isinstance(v, str):
        if v not in ("ideal", "separate"):
            raise smap.error(cp, f"expected ideal or separate (or a mapping with mode: separate), got {v!r}")
        v = {"mode": v}
    if not isinstance(v, dict):
        raise smap.error(cp, f"expected ideal, separate or a mapping, got {v!r}")
    check_keys(v, smap, cp, ["mode", "batch_frames", "unit_rate_value_ppm", *CLOCK_KEYS])
    mode = get_str(v, smap, cp, "mode", "separate", choices=["ideal", "separate"])
    values = {
        fname: get_number(v, smap, cp, key, default, minimum=0, maximum=1e4) * si
        for key, (fname, si, default) in CLOCK_KEYS.items()
    }
    exact = get_number(v, smap, cp, "unit_rate_value_ppm", None, minimum=-1e4, maximum=1e4)
    return ClockModel(
        mode=mode,
        batch_frames=_int(v, smap, cp, "batch_frames", 8, 1, 100000),
        unit_rate=None if exact is None else exact * PPM,
        **values,
    )


def _budget_inputs(d: dict, smap: SourceMap, p: KeyPath, site: Site, table: Table) -> BudgetInputs | None:
    """``realise_uncertainty_inputs: true``: the simulator draws (seeded) every type-B input the certificate's
    budget claims, within the bench's own stated uncertainties (local g anomaly, table attitude, rate, azimuth and
    axis orthogonality, the site latitude's assumed u)."""
    v = d.get("realise_uncertainty_inputs", False)
    if not isinstance(v, bool):
        raise smap.error(p + ("realise_uncertainty_inputs",), f"expected true or false, got {v!r}")
    if not v:
        return None
    return BudgetInputs(
        gravity_anomaly_std=site.g_uncertainty,
        attitude_error_bound=table.attitude_accuracy,
        rate_error_bound=table.rate_accuracy,
        azimuth_std=float(getattr(table, "azimuth_uncertainty", None) or 0.0),
        axis_tilt_bound=table.attitude_accuracy,
        latitude_std=DEFAULT_LATITUDE_U,
    )


def _band(d: dict, smap: SourceMap, p: KeyPath, fs: float) -> tuple[float, float]:
    if d.get("flicker_band_hz") is None:
        return (1e-4, 1.0)
    lo, hi = get_vector(d, smap, p, "flicker_band_hz", 2)
    if not 0 < lo < hi <= fs / 4:
        raise smap.error(
            p + ("flicker_band_hz",), f"need 0 < low < high ≤ sample rate/4 ({fs / 4:g} Hz), got {[lo, hi]}"
        )
    return (lo, hi)

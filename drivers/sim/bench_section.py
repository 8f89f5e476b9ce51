"""The ``simulation:`` section of a bench file, parsed by the simulator that owns it (SI out).

:func:`parse_simulation` turns the section (display units: µg, ppm, arcsec, °/h, ...) into a
:class:`~drivers.sim.config.SimConfig`; :mod:`benches.bench_config` calls it with the bench's site, table
and unit, which it reads only through the small protocols below (so the simulator does not import
``benches``). Errors are :class:`~core.yaml_source.ConfigError` naming file:line and the key path.
"""

from __future__ import annotations

from typing import Protocol

import numpy as np

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
from core.yaml_source import (
    KeyPath,
    SourceMap,
    check_keys,
    get_number,
    get_str,
    get_vector,
)
from core.yaml_source import get_components as _vec
from core.yaml_source import get_int as _int
from core.yaml_source import get_list_of_maps as _list_of_maps
from core.yaml_source import get_matrix as _matrix
from core.yaml_source import get_section as _section
from drivers.imu_unit.counts import CountScale
from drivers.protocols import AxisLimits, FaultCode
from drivers.sim.config import (
    CHANNELS,
    MAX_SEED,
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


def parse_simulation(d: dict, smap: SourceMap, site: Site, table: Table, unit: Unit) -> SimConfig:
    """Parse the bench file's ``simulation:`` mapping ``d`` into a :class:`SimConfig` (SI)."""
    p: KeyPath = ("simulation",)
    check_keys(
        d,
        smap,
        p,
        [
            "seed",
            "transport",
            "controller",
            "accelerometer",
            "gyro",
            "accel_noise",
            "gyro_noise",
            "temperature",
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
        ],
    )
    fs = unit.sample_rate
    z3 = (0.0, 0.0, 0.0)
    # accelerometer truth
    ad = _section(d, smap, p, "accelerometer", required=False) or {}
    ap = p + ("accelerometer",)
    check_keys(ad, smap, ap, ["bias_ug", "scale_ppm", "misalignment_arcsec", "quadratic_ug_g2", "lever_arm_mm"])
    accel = AccelTruth(
        bias=_vec(ad, smap, ap, "bias_ug", UG, z3),  # type: ignore[arg-type]
        scale=_vec(ad, smap, ap, "scale_ppm", PPM, z3),  # type: ignore[arg-type]
        misalignment=_vec(ad, smap, ap, "misalignment_arcsec", ARCSEC, (0.0,) * 6, length=6),  # type: ignore[arg-type]
        quadratic=_vec(ad, smap, ap, "quadratic_ug_g2", UG_PER_G2, z3),  # type: ignore[arg-type]
        lever_arms=_matrix(ad, smap, ap, "lever_arm_mm", MM, (z3, z3, z3)),
    )
    gd = _section(d, smap, p, "gyro", required=False) or {}
    gp = p + ("gyro",)
    check_keys(gd, smap, gp, ["bias_dph", "scale_ppm", "misalignment_arcsec", "g_sensitivity_dph_per_g",
                              "quadratic_ppm_per_dps", "asymmetry_ppm"])  # fmt: skip
    gyro = GyroTruth(
        bias=_vec(gd, smap, gp, "bias_dph", DEG_PER_HOUR, z3),  # type: ignore[arg-type]
        scale=_vec(gd, smap, gp, "scale_ppm", PPM, z3),  # type: ignore[arg-type]
        misalignment=_vec(gd, smap, gp, "misalignment_arcsec", ARCSEC, (0.0,) * 6, length=6),  # type: ignore[arg-type]
        g_sensitivity=_matrix(gd, smap, gp, "g_sensitivity_dph_per_g", DPH_PER_G, (z3, z3, z3)),
        quadratic=_vec(gd, smap, gp, "quadratic_ppm_per_dps", PPM / DEG, z3),  # type: ignore[arg-type]
        asymmetry=_vec(gd, smap, gp, "asymmetry_ppm", PPM, z3),  # type: ignore[arg-type]
    )
    # noise truth: defaults to the unit's configured noise
    nd = _section(d, smap, p, "accel_noise", required=False) or {}
    np_ = p + ("accel_noise",)
    check_keys(
        nd, smap, np_, ["vrw_ug_per_sqrt_hz", "bias_instability_ug", "random_walk_ug_per_sqrt_s", "flicker_band_hz"]
    )
    accel_noise = NoiseTruth(
        white=_vec(nd, smap, np_, "vrw_ug_per_sqrt_hz", UG_PER_SQRT_HZ, tuple(unit.noise.vrw), minimum=0),  # type: ignore[arg-type]
        bias_instability=_vec(nd, smap, np_, "bias_instability_ug", UG, tuple(unit.noise.bias_instability), minimum=0),  # type: ignore[arg-type]
        random_walk=_vec(nd, smap, np_, "random_walk_ug_per_sqrt_s", UG_PER_SQRT_S, z3, minimum=0),  # type: ignore[arg-type]
        flicker_band=_band(nd, smap, np_, fs),
    )
    nd = _section(d, smap, p, "gyro_noise", required=False) or {}
    np_ = p + ("gyro_noise",)
    check_keys(
        nd,
        smap,
        np_,
        ["arw_deg_per_sqrt_h", "bias_instability_dph", "rate_random_walk_dph_per_sqrt_h", "flicker_band_hz"],
    )
    gyro_noise = NoiseTruth(
        white=_vec(nd, smap, np_, "arw_deg_per_sqrt_h", DEG_PER_SQRT_HOUR, tuple(unit.noise.arw), minimum=0),  # type: ignore[arg-type]
        bias_instability=_vec(
            nd, smap, np_, "bias_instability_dph", DEG_PER_HOUR, tuple(unit.noise.gyro_bias_instability), minimum=0
        ),  # type: ignore[arg-type]
        random_walk=_vec(nd, smap, np_, "rate_random_walk_dph_per_sqrt_h", RATE_RW, z3, minimum=0),  # type: ignore[arg-type]
        flicker_band=_band(nd, smap, np_, fs),
    )
    # temperature
    temperature = None
    td = _section(d, smap, p, "temperature", required=False)
    if td is not None:
        tp = p + ("temperature",)
        check_keys(
            td,
            smap,
            tp,
            [
                "ambient_c",
                "warmup_rise_c",
                "warmup_tau_s",
                "accel_bias_ug_per_c",
                "accel_scale_ppm_per_c",
                "gyro_bias_dph_per_c",
                "gyro_scale_ppm_per_c",
            ],
        )
        temperature = TemperatureModel(
            ambient_c=get_number(td, smap, tp, "ambient_c", 23.0, minimum=-60, maximum=120),
            warmup_rise_c=get_number(td, smap, tp, "warmup_rise_c", 0.0, minimum=-50, maximum=100),
            warmup_tau=get_number(td, smap, tp, "warmup_tau_s", 600.0, minimum=0, exclusive_minimum=True),
            accel_bias_tc=_vec(td, smap, tp, "accel_bias_ug_per_c", UG, z3),  # type: ignore[arg-type]
            accel_scale_tc=_vec(td, smap, tp, "accel_scale_ppm_per_c", PPM, z3),  # type: ignore[arg-type]
            gyro_bias_tc=_vec(td, smap, tp, "gyro_bias_dph_per_c", DEG_PER_HOUR, z3),  # type: ignore[arg-type]
            gyro_scale_tc=_vec(td, smap, tp, "gyro_scale_ppm_per_c", PPM, z3),  # type: ignore[arg-type]
        )
    periodic = []
    for ip, item in _list_of_maps(d, smap, p, "periodic"):
        ch = get_str(item, smap, ip, "channel", choices=list(CHANNELS))
        key, si = _channel_unit(ch, smap, ip, item, "amplitude")
        check_keys(item, smap, ip, ["channel", "frequency_hz", key, "phase_deg"])
        periodic.append(
            PeriodicTerm(
                channel=ch,
                frequency_hz=get_number(
                    item, smap, ip, "frequency_hz", minimum=0, exclusive_minimum=True, maximum=fs / 2
                ),
                amplitude=get_number(item, smap, ip, key, minimum=0) * si,
                phase=get_number(item, smap, ip, "phase_deg", 0.0, minimum=-360, maximum=360) * DEG,
            )
        )
    arma = []
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
        arma.append(
            ArmaDrift(
                channel=ch, phi=coef["phi"], theta=coef["theta"], sigma=get_number(item, smap, ip, key, minimum=0) * si
            )
        )
    # table imperfections
    tbd = _section(d, smap, p, "table", required=False) or {}
    tp = p + ("table",)
    check_keys(
        tbd,
        smap,
        tp,
        [
            "encoder_bits",
            "position_jitter_arcsec",
            "rate_jitter_dps",
            "rate_jitter_tau_s",
            "overshoot_arcsec",
            "settle_frequency_hz",
            "settle_time_constant_s",
            "slew_fraction",
            "non_orthogonality_arcsec",
            "wobble_arcsec",
        ],
    )
    tm = TableModel(
        limits=table.limits,
        position_tolerance=table.position_tolerance,
        in_position_time=table.in_position_time,
        watchdog=table.watchdog,
        slew_fraction=get_number(tbd, smap, tp, "slew_fraction", 0.9, minimum=0, exclusive_minimum=True, maximum=1),
        overshoot=get_number(tbd, smap, tp, "overshoot_arcsec", 5.0, minimum=0) * ARCSEC,
        settle_frequency_hz=get_number(tbd, smap, tp, "settle_frequency_hz", 4.0, minimum=0, exclusive_minimum=True),
        settle_time_constant=get_number(
            tbd, smap, tp, "settle_time_constant_s", 0.08, minimum=0, exclusive_minimum=True
        ),
        encoder_bits=_int(tbd, smap, tp, "encoder_bits", 24, 0, 40),
        position_jitter=get_number(tbd, smap, tp, "position_jitter_arcsec", 0.1, minimum=0) * ARCSEC,
        rate_jitter=get_number(tbd, smap, tp, "rate_jitter_dps", 1e-4, minimum=0) * DEG,
        rate_jitter_tau=get_number(tbd, smap, tp, "rate_jitter_tau_s", 0.05, minimum=0, exclusive_minimum=True),
        non_orthogonality=_vec(tbd, smap, tp, "non_orthogonality_arcsec", ARCSEC, (0.0, 0.0), length=2),  # type: ignore[arg-type]
        wobble=get_number(tbd, smap, tp, "wobble_arcsec", 0.0, minimum=0, maximum=3600) * ARCSEC,
    )
    faults = []
    for ip, item in _list_of_maps(d, smap, p, "faults"):
        check_keys(item, smap, ip, ["time_s", "fault"])
        names = [f.name for f in FaultCode if f != FaultCode.NONE]
        faults.append(
            ScheduledFault(
                time=get_number(item, smap, ip, "time_s", minimum=0),
                fault=FaultCode[get_str(item, smap, ip, "fault", choices=names)],
            )
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
        periodic=tuple(periodic),
        arma=tuple(arma),
        anti_alias_hz=aa or None,
        timestamp_jitter=get_number(d, smap, p, "timestamp_jitter_us", 0.0, minimum=0, maximum=1e5) * 1e-6,
        drop_probability=get_number(d, smap, p, "drop_probability", 0.0, minimum=0, maximum=0.5),
        table=tm,
        faults=tuple(faults),
        seed=_int(d, smap, p, "seed", 0, 0, MAX_SEED),
        transport=get_str(d, smap, p, "transport", "in-process", choices=["in-process", "loopback"]),
        budget_inputs=_budget_inputs(d, smap, p, site, table),
        clocks=parse_clocks(d, smap, p),
        realtime=_realtime(d, smap, p),
    )


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
    budget claims, within the bench's own stated uncertainties (local g anomaly, table attitude and rate)."""
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

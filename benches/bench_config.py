"""Bench definitions: load a bench YAML file into frozen, SI dataclasses (format: ``benches/BENCH_FORMAT.md``).

Every user error is a :class:`~core.yaml_source.ConfigError` naming file:line, the key path, what is
wrong and what is allowed. Display units appear only in the YAML, in the key names (``rate_max_dps``,
``bias_ug``, ``lever_arm_mm``…), and are converted once here through ``analysis.units``.
"""

from __future__ import annotations

import datetime as _dt
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from analysis.earth import normal_gravity
from analysis.identification.budget import default_g_uncertainty
from analysis.identification.gyro import build as _gyro_model
from analysis.units import (
    ARCSEC,
    DEG,
    DEG_PER_HOUR,
    DEG_PER_SQRT_HOUR,
    G0,
    MM,
    PPM,
    UG,
    UG_PER_G2,
    UG_PER_SQRT_HZ,
    celsius_to_kelvin,
)
from benches import devices
from benches.results.recalibration import parse_configuration, parse_recalibration
from core.declare import Section, number, text
from core.yaml_source import (
    ConfigError,
    KeyPath,
    SourceMap,
    check_keys,
    get_mapping,
    get_number,
    get_str,
    load_yaml,
    load_yaml_text,
)
from core.yaml_source import get_components as _vec
from core.yaml_source import get_int as _int
from core.yaml_source import get_list_of_maps as _list_of_maps
from core.yaml_source import get_matrix as _matrix
from core.yaml_source import get_section as _section
from drivers.acutrol.settings import AclSettings
from drivers.aerosmith.settings import AerosmithSettings
from drivers.chamber.bench_section import ChamberSection
from drivers.imu_unit.counts import CountScale
from drivers.imu_unit.description import (
    DEFAULT_FRAME,
    FrameDescription,
    FrameFormat,
    compile_format,
    frame_path,
    load_frame,
    shipped_frames,
)
from drivers.imu_unit.serial_unit import count_format
from drivers.modbus.register_map import ModbusMap
from drivers.protocols import AXIS_NAMES, AxisLimits
from drivers.sim.bench_section import parse_simulation
from drivers.sim.config import (
    ACCEL_PARAM_NAMES,
    SimConfig,
)

__all__ = [
    "Ambient",
    "BenchConfig",
    "ConfigError",
    "NoiseSpec",
    "Site",
    "TurntableSpec",
    "UnitSpec",
    "load_bench",
    "noise_problem",
    "load_bench_text",
    "PARAM_GROUPS",
    "unit_frame_format",
]

GYRO_PARAM_NAMES: tuple[str, ...] = _gyro_model(full_g=True, quadratic=True, asymmetry=True).names
"""Every gyro-model parameter name (b 3, S 3, τ 6, G 9, S2 3, A 3) a bench may give a prior or limit for."""

# parameter groups of the 18-parameter model: YAML key stem, unit suffix, SI per display unit, names
PARAM_GROUPS: dict[str, tuple[str, float, tuple[str, ...]]] = {
    "bias": ("ug", UG, ACCEL_PARAM_NAMES[0:3]),
    "scale": ("ppm", PPM, ACCEL_PARAM_NAMES[3:6]),
    "misalignment": ("arcsec", ARCSEC, ACCEL_PARAM_NAMES[6:12]),
    "quadratic": ("ug_g2", UG_PER_G2, ACCEL_PARAM_NAMES[12:15]),
    "size_effect": ("mm", MM, ACCEL_PARAM_NAMES[15:18]),
    # the gyro model's (docs/methods/gyro-calibration.md): all variants' names, so a bench may state any
    "gyro_bias": ("dph", DEG_PER_HOUR, GYRO_PARAM_NAMES[0:3]),
    "gyro_scale": ("ppm", PPM, GYRO_PARAM_NAMES[3:6]),
    "gyro_misalignment": ("arcsec", ARCSEC, GYRO_PARAM_NAMES[6:12]),
    "gyro_g_sensitivity": ("dph_per_g", DEG_PER_HOUR / G0, GYRO_PARAM_NAMES[12:21]),
    "gyro_quadratic": ("ppm_per_dps", PPM / DEG, GYRO_PARAM_NAMES[21:24]),
    "gyro_asymmetry": ("ppm", PPM, GYRO_PARAM_NAMES[24:27]),
}
_NAME_UNIT = {name: (suffix, si) for suffix, si, names in PARAM_GROUPS.values() for name in names}
_ALL_PARAM_NAMES = ACCEL_PARAM_NAMES + GYRO_PARAM_NAMES
PARAM_MAX: dict[str, float] = {
    "ug": 1e6, "ppm": 1e6, "arcsec": 360_000.0, "ug_g2": 1e6, "mm": 10_000.0, "dph": 3.6e6, "dph_per_g": 1e5,
    "ppm_per_dps": 1e6,
}  # fmt: skip
"""Largest prior / limit a bench file may give, display units by key suffix (1 g, 100 %, 100°, 1 g/g², 10 m):
beyond that the number is a typo, not a datasheet bound."""


@dataclass(frozen=True)
class Ambient:
    """The laboratory's ambient conditions during a calibration, as the bench file states them (``site.ambient``).

    ISO/IEC 17025 (7.8.2.1, 7.8.4.1) asks a certificate for the conditions under which the calibration was
    made; the unit's own temperature sensor is not the laboratory's. Each field is None when not stated.

    Attributes
    ----------
    temperature : float or None
        Air temperature, K.
    temperature_tolerance : float or None
        The controlled band ± about it, K.
    relative_humidity : float or None
        Relative humidity, fraction (0.45 = 45 %).
    pressure : float or None
        Air pressure, Pa.
    """

    temperature: float | None = None
    temperature_tolerance: float | None = None
    relative_humidity: float | None = None
    pressure: float | None = None

    @property
    def stated(self) -> bool:
        """True when the bench file states at least the laboratory temperature."""
        return self.temperature is not None


@dataclass(frozen=True)
class Site:
    """Where the bench stands: latitude (rad), height (m), measured local g (m/s² or None), ambient conditions."""

    name: str
    latitude: float
    height: float
    g_measured: float | None = None
    g_uncertainty_given: float | None = None
    ambient: Ambient = field(default_factory=Ambient)

    @property
    def g_uncertainty(self) -> float:
        """Standard uncertainty of :attr:`g`, m/s²: the bench's ``g_uncertainty_mgal`` if given, else 0.1 mGal
        for a measured g and 30 mGal (a typical free-air anomaly) for WGS-84 normal gravity."""
        if self.g_uncertainty_given is not None:
            return self.g_uncertainty_given
        return default_g_uncertainty(self.g_measured is not None)

    @property
    def g(self) -> float:
        """Local gravity, m/s²: the measured value if given, else WGS-84 normal gravity at the site."""
        return self.g_measured if self.g_measured is not None else normal_gravity(self.latitude, self.height)

    @property
    def g_source(self) -> str:
        """Where :attr:`g` comes from, for certificates."""
        if self.g_measured is not None:
            return "measured"
        return f"WGS-84 normal gravity at φ = {math.degrees(self.latitude):.4f}°, h = {self.height:.1f} m"


@dataclass(frozen=True)
class TurntableSpec:
    """The table: driver, address, limits (SI) and controller behaviour."""

    driver: str
    address: str | None
    limits: tuple[AxisLimits, AxisLimits, AxisLimits]
    position_tolerance: float
    in_position_time: float
    attitude_accuracy: float
    heartbeat_period: float
    watchdog: float | None
    model: str = ""
    serial_number: str = ""
    float_word_order: str | None = None  # Modbus: overrides the map's word order when given
    rate_accuracy: float = 0.0
    """Rate accuracy bound of the table (relative, ±; bench key ``rate_accuracy_ppm``); 0: not stated."""
    modbus_map: ModbusMap | None = None  # Modbus tables; None: the shipped map
    resource: str | None = None  # VISA resource string (driver acutrol)
    acl: AclSettings | None = None  # ACL open points (driver acutrol, or a simulated ACUTROL)
    rate_tolerance: float = 0.01 * DEG  # rad/s: at-rate / at-rest window of host-decided settling
    azimuth_uncertainty: float | None = None
    """Standard uncertainty of the outer gimbal's zero azimuth (East), rad (``azimuth_uncertainty_arcsec``);
    None: not stated (the certificate then assumes one and says so)."""

    @property
    def at_rate_tolerance(self) -> float:
        """The host's at-rate window, rad/s: the stated tolerance plus the table's stated rate accuracy at its
        fastest axis (a table that turns 300 ppm fast at 60 °/s is 0.018 °/s off its command, and at rate)."""
        return self.rate_tolerance + self.rate_accuracy * max(lim.rate_max for lim in self.limits)

    sim_controller: str = field(default_factory=lambda: devices.default_simulated_controller())
    """Simulated benches: which controller the simulator speaks (``simulation.controller``, :mod:`benches.devices`)."""
    aerosmith: AerosmithSettings | None = None  # Ideal Aerosmith open points (driver ideal-aerosmith or simulated)
    settings: Any = None
    """The own settings of a controller registered outside the shipped ones
    (:class:`benches.devices.ControllerKind`)."""


@dataclass(frozen=True)
class NoiseSpec:
    """Configured (datasheet) noise of the unit, SI per body axis.

    vrw : (3,) accel white density, m/s²/√Hz. bias_instability : (3,) m/s².
    arw : (3,) rad/√s. gyro_bias_instability : (3,) rad/s.
    """

    vrw: np.ndarray
    bias_instability: np.ndarray
    arw: np.ndarray
    gyro_bias_instability: np.ndarray


@dataclass(frozen=True)
class UnitSpec:
    """The inertial unit: driver, link, sample rate, count scale, mounting C_b^t, noise and prior (1σ, SI)."""

    driver: str
    address: str | None
    baudrate: int
    model: str
    serial_number: str
    sample_rate: float
    scale: CountScale
    mounting: np.ndarray
    noise: NoiseSpec
    prior: dict[str, float] = field(default_factory=dict)
    latency: float = 0.0  # s: output latency (anti-alias group delay) from the datasheet
    frame: str = "tablebench-v1"  # frame format: shipped name or description path (drivers/imu_unit/frames/README.md)
    frame_options: dict[str, Any] = field(default_factory=dict)  # the unit's output configuration
    frame_desc: FrameDescription | None = None
    keep_raw: bool = False  # keep the raw serial stream as RUN_DIR/unit-raw.bin
    gyro_g_sensitivity: str = "diagonal"  # identify the gyro's g-sensitivity as its diagonal or the "full" 3 × 3
    time_reference: str | None = None  # hardware timing: "pps" or "time_tag" (one clock); None: estimated


@dataclass(frozen=True)
class BenchConfig:
    """A loaded bench file (SI). ``simulation`` is present iff the bench is simulated."""

    name: str
    path: Path
    text: str
    site: Site
    turntable: TurntableSpec
    unit: UnitSpec
    limits: dict[str, float]
    simulation: SimConfig | None
    reference_standards: tuple[ReferenceStandard, ...] = ()
    chamber: ChamberSection | None = None
    """The temperature chamber (``chamber:`` section, docs/protocols/chambers.md), None without one."""
    auxiliary: dict[str, Any] = field(default_factory=dict)
    """The bench's auxiliary devices: section key → settings, for every registered kind it names
    (:func:`benches.devices.register_auxiliary`; the chamber is one)."""


@dataclass(frozen=True)
class ReferenceStandard:
    """A reference standard the bench's traceability rests on (bench key ``reference_standards``).

    Attributes
    ----------
    name : str
        What it is and what it provides (e.g. "turntable angle encoders (attitude)", "site gravimeter survey").
    serial_number, certificate : str
        Its identification and the calibration certificate that makes it traceable.
    calibrated_by : str
        The laboratory that calibrated it.
    due : datetime.date
        Calibration due date; a calibration performed after it is flagged on the certificate.
    """

    name: str
    serial_number: str
    certificate: str
    calibrated_by: str
    due: _dt.date


# ---- small helpers ---------------------------------------------------------------------------------


def _opt_str(data: dict, smap: SourceMap, path: KeyPath, key: str) -> str | None:
    v = data.get(key)
    if v is None:
        return None
    if isinstance(v, (int, float)) and not isinstance(v, bool):
        return str(v)
    return get_str(data, smap, path, key)


# ---- sections --------------------------------------------------------------------------------------


def _site(d: dict, smap: SourceMap) -> Site:
    p: KeyPath = ("site",)
    check_keys(d, smap, p, ["name", "latitude_deg", "height_m", "g_measured_mps2", "g_uncertainty_mgal", "ambient"])
    g = get_number(d, smap, p, "g_measured_mps2", None, minimum=9.7, maximum=9.9)
    ug = get_number(d, smap, p, "g_uncertainty_mgal", None, minimum=0, exclusive_minimum=True, maximum=1000)
    return Site(
        name=get_str(d, smap, p, "name", ""),
        latitude=get_number(d, smap, p, "latitude_deg", minimum=-90, maximum=90) * DEG,
        height=get_number(d, smap, p, "height_m", 0.0, minimum=-500, maximum=9000),
        g_measured=g,
        g_uncertainty_given=None if ug is None else ug * 1e-5,
        ambient=_ambient(_section(d, smap, p, "ambient", required=False), smap),
    )


def _ambient(d: dict | None, smap: SourceMap) -> Ambient:
    """``site.ambient`` (optional): the laboratory's conditions, °C / % / hPa in the file, SI inside."""
    if d is None:
        return Ambient()
    p: KeyPath = ("site", "ambient")
    check_keys(d, smap, p, ["temperature_c", "temperature_tolerance_c", "humidity_percent", "pressure_hpa"])
    t = get_number(d, smap, p, "temperature_c", None, minimum=-40, maximum=80)
    tol = get_number(d, smap, p, "temperature_tolerance_c", None, minimum=0, exclusive_minimum=True, maximum=50)
    if tol is not None and t is None:
        raise smap.error(p + ("temperature_tolerance_c",), "needs temperature_c (the band is about it)")
    rh = get_number(d, smap, p, "humidity_percent", None, minimum=0, maximum=100)
    hpa = get_number(d, smap, p, "pressure_hpa", None, minimum=500, maximum=1100)
    return Ambient(
        temperature=None if t is None else celsius_to_kelvin(t),
        temperature_tolerance=tol,
        relative_humidity=None if rh is None else rh / 100.0,
        pressure=None if hpa is None else hpa * 100.0,
    )


def _axis(d: dict, smap: SourceMap, p: KeyPath) -> AxisLimits:
    check_keys(d, smap, p, ["rate_max_dps", "accel_max_dps2", "position_min_deg", "position_max_deg"])
    rate = get_number(d, smap, p, "rate_max_dps", minimum=0, exclusive_minimum=True, maximum=3600)
    acc = get_number(d, smap, p, "accel_max_dps2", minimum=0, exclusive_minimum=True, maximum=1e5)
    lo = get_number(d, smap, p, "position_min_deg", None)
    hi = get_number(d, smap, p, "position_max_deg", None)
    if (lo is None) != (hi is None):
        missing = "position_max_deg" if hi is None else "position_min_deg"
        raise smap.error(p + (missing,), "give both position_min_deg and position_max_deg, or neither (continuous)")
    if lo is not None and hi is not None and not lo < hi:
        raise smap.error(p + ("position_max_deg",), f"must be greater than position_min_deg ({lo:g})")
    return AxisLimits(
        rate_max=rate * DEG,
        accel_max=acc * DEG,
        position_min=None if lo is None else lo * DEG,
        position_max=None if hi is None else hi * DEG,
    )


def _table_axes(d: dict, smap: SourceMap, p: KeyPath, check_axis: Any = None) -> list[AxisLimits]:
    """``turntable.axes``: the limits of each gimbal, or ``absent`` for one the table does not have;
    ``check_axis(name)`` refuses an axis the controller cannot have (before its keys are read)."""
    axes = _section(d, smap, p, "axes")
    assert axes is not None
    check_keys(axes, smap, p + ("axes",), list(AXIS_NAMES))
    limits = []
    for name in AXIS_NAMES:
        if axes.get(name) == "absent":  # a gimbal the table does not have (a single-axis table's other two)
            limits.append(AxisLimits.absent_axis())
            continue
        if check_axis is not None:
            check_axis(name)
        ad = _section(axes, smap, p + ("axes",), name)
        assert ad is not None
        limits.append(_axis(ad, smap, p + ("axes", name)))
    return limits


TURNTABLE = Section(
    number("position_tolerance_arcsec", 2.0 * ARCSEC, unit=ARCSEC, minimum=0, exclusive_minimum=True,
           attr="position_tolerance"),
    number("rate_tolerance_dps", 0.01 * DEG, unit=DEG, minimum=0, exclusive_minimum=True, attr="rate_tolerance"),
    number("in_position_time_s", 0.2, minimum=0, attr="in_position_time"),
    number("attitude_accuracy_arcsec", 1.0 * ARCSEC, unit=ARCSEC, minimum=0, attr="attitude_accuracy"),
    number("rate_accuracy_ppm", 0.0, unit=1e-6, minimum=0, maximum=1e5, attr="rate_accuracy"),
    number("azimuth_uncertainty_arcsec", None, unit=ARCSEC, minimum=0, maximum=36000, attr="azimuth_uncertainty"),
    number("heartbeat_period_s", 0.5, minimum=0, exclusive_minimum=True, attr="heartbeat_period"),
    number("watchdog_s", 2.0, minimum=0, attr="watchdog"),
    text("float_word_order", None, choices=["big", "little"]),
)  # fmt: skip
"""The ``turntable`` keys every controller takes (SI); ``driver``, the link (``address`` or ``resource``),
``model``, ``serial_number``, ``axes`` and each controller's own keys (:mod:`benches.devices`) are read by
:func:`_turntable`."""


def _turntable_keys() -> list[str]:
    own = [k for kind in devices.controllers() for k in kind.own_keys]
    return ["driver", "address", "resource", *own, "model", "serial_number", "axes", *TURNTABLE.keys()]


def _link_checks(d: dict, smap: SourceMap, p: KeyPath, driver: str, kind: devices.ControllerKind) -> str | None:
    """The controller's link (``resource`` or ``address``) checked against the driver; its value (None: none)."""
    address, resource = _opt_str(d, smap, p, "address"), _opt_str(d, smap, p, "resource")
    real = driver != devices.SIMULATED
    link = resource if kind.link_key == "resource" else address
    if real and not link:
        raise smap.error(p + (kind.link_key,), kind.link_required)
    if resource and not (real and kind.link_key == "resource"):
        names = " or ".join(repr(k.name) for k in devices.controllers() if k.link_key == "resource")
        raise smap.error(p + ("resource",), f"is only for driver {names} (this table is {driver!r})")
    if real and kind.link_key != "address" and address:
        raise smap.error(
            p + ("address",), f"is not used by driver {driver!r}; name the controller with {kind.link_key}:"
        )
    for other in devices.controllers():
        for key, message in other.own_keys.items():
            if other is not kind and d.get(key) is not None:
                raise smap.error(p + (key,), message)
    if kind.no_watchdog:
        for key in ("heartbeat_period_s", "watchdog_s"):
            if d.get(key) is not None:
                raise smap.error(
                    p + (key,),
                    f"{kind.no_watchdog} has no host heartbeat or watchdog; remove this key (the host stops the axes "
                    "itself on every exit path)",
                )
    return link


def _turntable(d: dict, smap: SourceMap, sim_controller: str | None) -> TurntableSpec:
    """The ``turntable`` section: :data:`TURNTABLE`, then the controller's own settings through the device registry
    (:mod:`benches.devices`: the controller a real ``driver`` or the simulated ``simulation.controller`` names)."""
    p: KeyPath = ("turntable",)
    check_keys(d, smap, p, _turntable_keys())
    driver = get_str(d, smap, p, "driver", choices=[devices.SIMULATED, *devices.controller_names()])
    sim_controller = sim_controller or devices.default_simulated_controller()
    kind = devices.controller_of(driver, sim_controller)
    link = _link_checks(d, smap, p, driver, kind)
    own: dict[str, Any] = {}
    if kind.parse_settings is not None:
        own = kind.parse_settings(d, smap, p, link=link, simulated=driver == devices.SIMULATED)
    check_axis = None
    if kind.check_axis is not None:
        axis_check = kind.check_axis
        check_axis = lambda name: axis_check(own, name, smap, p)  # noqa: E731
    limits = _table_axes(d, smap, p, check_axis)
    if kind.check_limits is not None:
        kind.check_limits(own, limits, smap, p)
    values = TURNTABLE.read(d, smap, p, check=False)
    wd, hb = values["watchdog"], values["heartbeat_period"]
    if wd and hb >= wd:
        raise smap.error(p + ("heartbeat_period_s",), f"{hb:g} s must be shorter than watchdog_s ({wd:g} s)")
    values["watchdog"] = None if kind.no_watchdog else (wd or None)
    return TurntableSpec(
        driver=driver,
        address=_opt_str(d, smap, p, "address"),
        limits=(limits[0], limits[1], limits[2]),
        model=str(d.get("model") or ""),
        serial_number=str(d.get("serial_number") or ""),
        resource=_opt_str(d, smap, p, "resource"),
        sim_controller=sim_controller,
        **values,
        **own,
    )


def _optional_arcsec(d: dict, smap: SourceMap, p: KeyPath, key: str) -> float | None:
    """An optional angle in arcsec (0 … 10°) as rad; None when the bench does not state it."""
    return None if d.get(key) is None else get_number(d, smap, p, key, minimum=0, maximum=36000) * ARCSEC


def _param_map(d: dict | None, smap: SourceMap, p: KeyPath, positive: bool) -> dict[str, float]:
    """Per-parameter values from group keys (``bias_ug: 300``) and/or single keys (``b_x_ug: 500``), SI."""
    if d is None:
        return {}
    allowed = [f"{g}_{suffix}" for g, (suffix, _, _) in PARAM_GROUPS.items()]
    allowed += [f"{n}_{_NAME_UNIT[n][0]}" for n in _ALL_PARAM_NAMES]
    check_keys(d, smap, p, allowed)
    out: dict[str, float] = {}
    lo = dict(minimum=0.0, exclusive_minimum=True) if positive else {}
    for g, (suffix, si, names) in PARAM_GROUPS.items():
        key = f"{g}_{suffix}"
        if key in d:
            v = get_number(d, smap, p, key, maximum=PARAM_MAX[suffix], **lo)
            out.update({n: v * si for n in names})
    for n in _ALL_PARAM_NAMES:
        suffix, si = _NAME_UNIT[n]
        key = f"{n}_{suffix}"
        if key in d:
            out[n] = get_number(d, smap, p, key, maximum=PARAM_MAX[suffix], **lo) * si
    return out


def _unit(d: dict, smap: SourceMap) -> UnitSpec:
    p: KeyPath = ("unit",)
    check_keys(
        d,
        smap,
        p,
        [
            "driver",
            "address",
            "baudrate",
            "model",
            "serial_number",
            "sample_rate_hz",
            "latency_ms",
            "scale",
            "mounting",
            "noise",
            "prior",
            "gyro_g_sensitivity",
            "frame",
            "frame_options",
            "keep_raw",
            "time_reference",
            "configuration",
        ],
    )
    driver = get_str(d, smap, p, "driver", choices=devices.unit_names())
    address = _opt_str(d, smap, p, "address")
    if driver != devices.SIMULATED and not address:
        raise smap.error(p + ("address",), devices.unit_kind(driver).link_required)
    frame = get_str(d, smap, p, "frame", DEFAULT_FRAME)
    sc = _section(d, smap, p, "scale", required=frame == DEFAULT_FRAME)
    if sc is None:  # another frame format carries its own scale; the simulator's internal counts are fine
        # internal counts are int32: 1e-3 °/h per count reaches ±596 °/s (a KVH 1750 ±490 °/s, a STIM300
        # ±400 °/s); 1e-4 °/h clipped every rate above 59.65 °/s (a 90° step peaks at 85 °/s)
        scale = CountScale(accel_lsb=0.01 * UG, gyro_lsb=1e-3 * DEG_PER_HOUR, temperature_lsb=0.01)
    else:
        sp = p + ("scale",)
        check_keys(sc, smap, sp, ["accel_ug_per_count", "gyro_dph_per_count", "temperature_c_per_count"])
        scale = CountScale(
            accel_lsb=get_number(sc, smap, sp, "accel_ug_per_count", minimum=0, exclusive_minimum=True) * UG,
            gyro_lsb=get_number(sc, smap, sp, "gyro_dph_per_count", minimum=0, exclusive_minimum=True) * DEG_PER_HOUR,
            temperature_lsb=get_number(
                sc, smap, sp, "temperature_c_per_count", 0.01, minimum=0, exclusive_minimum=True
            ),
        )
    sample_rate = get_number(d, smap, p, "sample_rate_hz", minimum=1, maximum=100_000)
    frame_desc, frame_options = _unit_frame(d, smap, p, frame, sample_rate)
    keep_raw = d.get("keep_raw", False)
    if not isinstance(keep_raw, bool):
        raise smap.error(p + ("keep_raw",), f"expected true or false, got {keep_raw!r}")
    mount = np.asarray(_matrix(d, smap, p, "mounting", 1.0, ((1.0, 0, 0), (0, 1.0, 0), (0, 0, 1.0))), dtype=float)
    if not np.allclose(mount.T @ mount, np.eye(3), atol=1e-6) or np.linalg.det(mount) < 0:
        raise smap.error(p + ("mounting",), "must be a proper rotation matrix C_b^t (orthonormal rows, det +1)")
    nd = _section(d, smap, p, "noise")
    assert nd is not None
    npth = p + ("noise",)
    check_keys(
        nd, smap, npth, ["vrw_ug_per_sqrt_hz", "bias_instability_ug", "arw_deg_per_sqrt_h", "gyro_bias_instability_dph"]
    )
    noise = NoiseSpec(
        # > 0: the identification weights every sample by it (R = VRW² fs); 0 would claim a noise-free unit
        vrw=np.array(_vec(nd, smap, npth, "vrw_ug_per_sqrt_hz", UG_PER_SQRT_HZ, minimum=0, exclusive_minimum=True)),
        bias_instability=np.array(_vec(nd, smap, npth, "bias_instability_ug", UG, (0.0,) * 3, minimum=0)),
        arw=np.array(_vec(nd, smap, npth, "arw_deg_per_sqrt_h", DEG_PER_SQRT_HOUR, (0.0,) * 3, minimum=0)),
        gyro_bias_instability=np.array(
            _vec(nd, smap, npth, "gyro_bias_instability_dph", DEG_PER_HOUR, (0.0,) * 3, minimum=0)
        ),
    )
    prior = _param_map(_section(d, smap, p, "prior", required=False), smap, p + ("prior",), positive=True)
    return UnitSpec(
        driver=driver,
        address=address,
        baudrate=_int(d, smap, p, "baudrate", 921600, 300, 20_000_000),
        model=str(d.get("model") or ""),
        serial_number=str(d.get("serial_number") or ""),
        sample_rate=sample_rate,
        scale=scale,
        mounting=mount,
        noise=noise,
        prior=prior,
        latency=get_number(d, smap, p, "latency_ms", 0.0, minimum=0.0, maximum=1000.0) * 1e-3,
        frame=frame,
        frame_options=frame_options,
        frame_desc=frame_desc,
        keep_raw=keep_raw,
        gyro_g_sensitivity=get_str(d, smap, p, "gyro_g_sensitivity", "diagonal", choices=("diagonal", "full")),
        time_reference=get_str(d, smap, p, "time_reference", None, choices=["pps", "time_tag"]),
    )


def _unit_frame(
    d: dict, smap: SourceMap, p: KeyPath, frame: str, rate: float
) -> tuple[FrameDescription | None, dict[str, Any]]:
    """Load ``unit.frame`` (shipped name or path relative to the bench file) and check ``unit.frame_options``."""
    od = _section(d, smap, p, "frame_options", required=False) or {}
    opts = {k: (str(int(v)) if isinstance(v, float) and v.is_integer() else v) for k, v in od.items()}
    opts = {k: (str(v) if isinstance(v, int) and not isinstance(v, bool) else v) for k, v in opts.items()}
    bench_file = Path(smap.file)
    try:
        path = frame_path(frame, bench_file.parent)
    except KeyError:
        raise smap.error(
            p + ("frame",), f"unknown frame format {frame!r}; shipped: {', '.join(shipped_frames())}, or a .yaml path"
        ) from None
    if not path.exists():
        if not bench_file.exists():  # a bench text kept in a recording: the description may live elsewhere
            return None, opts
        raise smap.error(p + ("frame",), f"frame description {str(path)!r} not found")
    desc = load_frame(str(path))
    if frame == DEFAULT_FRAME and od:
        raise smap.error(p + ("frame_options",), "the tablebench-v1 frame takes its scale from unit.scale")
    if frame != DEFAULT_FRAME:
        try:
            compile_format(desc, opts, rate, where="frame_options")
        except ValueError as exc:
            raise smap.error(p + ("frame_options",), str(exc).removeprefix("frame_options: ")) from None
    return desc, opts


def unit_frame_format(unit: UnitSpec) -> FrameFormat:
    """The unit's compiled frame format (``tablebench-v1`` takes its count scale from ``unit.scale``).

    Raises
    ------
    ConfigError
        The description named by a recorded bench cannot be found any more.
    """
    if unit.frame == DEFAULT_FRAME:
        return count_format(unit.scale, unit.sample_rate)
    desc = unit.frame_desc if unit.frame_desc is not None else load_frame(unit.frame)
    return compile_format(desc, unit.frame_options, unit.sample_rate)


def load_bench_text(text: str, file: str | Path = "<input>") -> BenchConfig:
    """Parse a bench from YAML ``text`` (``file`` names it in errors). See :func:`load_bench`."""
    data, smap = load_yaml_text(text, file)
    return _build(data, smap, text, Path(str(file)))


def load_bench(path: str | Path) -> BenchConfig:
    """Load a bench YAML file into a :class:`BenchConfig` (SI).

    Raises
    ------
    ConfigError
        With file:line, key path, the problem and what is allowed.
    """
    data, smap, text = load_yaml(path)
    return _build(data, smap, text, Path(path))


def _build(data: Any, smap: SourceMap, text: str, path: Path) -> BenchConfig:
    if data is None:
        raise ConfigError(smap.file, None, "the bench file is empty; see benches/BENCH_FORMAT.md")
    root = get_mapping(data, smap, ())
    check_keys(
        root,
        smap,
        (),
        ["name", "site", "turntable", "unit", "limits", "simulation", "reference_standards",
         *devices.auxiliary_keys(), "recalibration"],
    )  # fmt: skip
    parse_recalibration(root.get("recalibration"), smap)  # the registry's settings (docs/registry.md)
    parse_configuration(root.get("unit"), smap)
    name = get_str(root, smap, (), "name")
    site = _site(_section(root, smap, (), "site"), smap)  # type: ignore[arg-type]
    sim_raw = root.get("simulation")
    sim_controller = None
    if isinstance(sim_raw, dict):
        sim_controller = get_str(
            sim_raw,
            smap,
            ("simulation",),
            "controller",
            devices.default_simulated_controller(),
            choices=devices.simulated_controller_names(),
        )
    table = _turntable(_section(root, smap, (), "turntable"), smap, sim_controller)  # type: ignore[arg-type]
    unit = _unit(_section(root, smap, (), "unit"), smap)  # type: ignore[arg-type]
    limits = _param_map(_section(root, smap, (), "limits", required=False), smap, ("limits",), positive=True)
    sim_d = _section(root, smap, (), "simulation", required=False)
    simulated = devices.SIMULATED in (table.driver, unit.driver)
    if simulated and sim_d is None:
        raise smap.error(("simulation",), "is required when a driver is 'sim' (add a simulation: section)")
    if sim_d is not None and not (table.driver == unit.driver == devices.SIMULATED):
        raise smap.error(("simulation",), "is only allowed when both turntable.driver and unit.driver are 'sim'")
    sim = parse_simulation(sim_d, smap, site, table, unit) if sim_d is not None else None
    auxiliary, sim = _auxiliary(root, smap, sim)
    return BenchConfig(
        name=name,
        path=path,
        text=text,
        site=site,
        turntable=table,
        unit=unit,
        limits=limits,
        simulation=sim,
        reference_standards=_reference_standards(root, smap),
        chamber=auxiliary.get("chamber"),
        auxiliary=auxiliary,
    )


def _auxiliary(root: dict, smap: SourceMap, sim: SimConfig | None) -> tuple[dict[str, Any], SimConfig | None]:
    """The auxiliary devices the bench names (:mod:`benches.devices`): section key → settings; a simulated device
    needs a simulated bench, whose world it may change (``AuxiliaryKind.simulation``)."""
    out: dict[str, Any] = {}
    for key in devices.auxiliary_keys():
        if root.get(key) is None:
            continue
        kind = devices.auxiliary(key)
        settings = kind.parse(root[key], smap, (key,))
        if kind.simulated(settings):
            if sim is None:
                raise smap.error((key, "driver"), "sim is only allowed on a simulated bench (simulation: section)")
            if kind.simulation is not None:
                sim = kind.simulation(sim, settings)
        elif sim is not None:
            raise smap.error((key, "driver"), f"a simulated bench needs driver: sim for its {key}")
        out[key] = settings
    return out, sim


def noise_problem(config: BenchConfig) -> str | None:
    """Why the bench's configured noise cannot weight the whole unit's identification, or None if it can.

    The ONE "is this bench usable" rule of the noise section, shared by ``check``, ``plan`` and ``run``
    (:func:`benches.session.prepare`) and the identification (:func:`benches.identify.configured_noise_variance`):
    the velocity random walk is > 0 by the loader; the gyro's angle random walk must be > 0 on every axis too,
    since the identification weights every gyro sample by it (R = ARW² fs).
    """
    if np.any(np.asarray(config.unit.noise.arw, dtype=float) <= 0):
        return (
            f"bench {config.name!r}: unit.noise.arw_deg_per_sqrt_h is missing or zero; the gyro identification "
            "needs the datasheet angle random walk; state it (a recording made already can be identified with "
            "--noise warm-up)"
        )
    return None


def chamber_limits(config: Any) -> tuple[float, float] | None:
    """A bench's chamber set-point limits (K) for the procedure compiler; None without a chamber."""
    chamber = getattr(config, "chamber", None)
    if chamber is None:
        return None
    s = chamber.config.settings
    return s.setpoint_min, s.setpoint_max


def _reference_standards(d: dict, smap: SourceMap) -> tuple[ReferenceStandard, ...]:
    """``reference_standards:`` (optional): a list of {name, serial_number, certificate, calibrated_by, due}."""
    out = []
    for ip, item in _list_of_maps(d, smap, (), "reference_standards"):
        check_keys(item, smap, ip, ["name", "serial_number", "certificate", "calibrated_by", "due"])
        due_v = item.get("due")
        if isinstance(due_v, _dt.date):
            due = due_v
        else:
            try:
                due = _dt.date.fromisoformat(str(due_v))
            except ValueError:
                raise smap.error(ip + ("due",), f"expected a calibration due date YYYY-MM-DD, got {due_v!r}") from None
        out.append(
            ReferenceStandard(
                name=get_str(item, smap, ip, "name"),
                serial_number=get_str(item, smap, ip, "serial_number", ""),
                certificate=get_str(item, smap, ip, "certificate"),
                calibrated_by=get_str(item, smap, ip, "calibrated_by", ""),
                due=due,
            )
        )
    return tuple(out)

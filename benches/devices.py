"""Devices by name: the ONE registry of what a bench file can name — turntable controllers, inertial units
and auxiliary devices — with, for each, its settings parser, its connect function and its simulated twin.

A bench file names a device by a string (``turntable.driver: acutrol``, ``simulation.controller: modbus``,
``auxiliary: {chamber: {driver: watlow-f4, …}}``); this module is the only place those strings are
resolved. The bench loader (:mod:`benches.bench_config`) asks it which names exist and parses each device's
own settings through it; the factory (:mod:`benches.factory`) asks it to open the device on hardware
(``connect``) or to build its simulated twin on the one simulated world (``twin``).

Adding a device is a registration, not an edit of the loader or the factory::

    from benches import devices
    devices.register_auxiliary(devices.AuxiliaryKind(name="my-probe", parse=..., connect=..., twin=...))

(see ``docs/extending.md``). Connect and twin functions import their drivers when called, so naming a
device never loads a driver library (``tablebench --help`` stays light).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from core.yaml_source import KeyPath, SourceMap, check_keys, get_mapping, get_number, get_str
from core.yaml_source import get_int as _int
from drivers.acutrol.settings import AclSettings, default_profile
from drivers.modbus.register_map import load_modbus_map
from drivers.protocols import AXIS_NAMES
from drivers.sim.acl_controller import SIM_TIME_VARIABLE

if TYPE_CHECKING:  # type only: the drivers import pyvisa, pymodbus, scipy (tablebench --help)
    from drivers.connect import Connection
    from drivers.protocols import Readable
    from drivers.sim.table_twins import TableTwin
    from drivers.sim.world import SimulatedWorld

TurntableSpec = Any
"""A loaded ``turntable`` section (:class:`benches.bench_config.TurntableSpec`; not imported: the loader imports
this module)."""


# ---- turntable controllers -------------------------------------------------------------------------------------


@dataclass(frozen=True)
class ControllerKind:
    """A turntable controller a bench can name.

    Attributes
    ----------
    name : str
        ``turntable.driver`` of a real bench (``acutrol``, ``modbus-tcp``).
    twins : dict
        ``simulation.controller`` name → ``(turntable spec, loopback_min_watchdog) -> TableTwin``: the simulated
        controllers that speak this controller's protocol (:mod:`drivers.sim.table_twins`).
    title : str
        What it is, for messages ("an ACUTROL table").
    link_key : str
        The ``turntable`` key that says where the controller is (``resource`` or ``address``).
    link_required : str
        The message when a real bench lacks ``link_key``.
    settings_key : str or None
        The ``turntable`` sub-section of this protocol's own settings (``acl``), None if it has none.
    exclusive_keys : tuple of str
        ``turntable`` keys only this controller takes (``modbus_map``); another controller refuses them.
    host_watchdog : bool
        True if the protocol has a host heartbeat/watchdog (``heartbeat_period_s``, ``watchdog_s`` apply).
    no_watchdog : str
        Without one: why (the start of the message refusing those keys).
    parse_settings : callable
        ``(turntable section, smap, path, *, link, simulated, limits) -> dict``: this protocol's own settings as
        :class:`benches.bench_config.TurntableSpec` fields (``acl``, ``modbus_map``; a new controller: ``settings``).
    connect : callable
        ``(turntable spec, timeout) -> drivers.connect.Connection`` with ``.where``: the real link.
    """

    name: str
    title: str
    link_key: str
    link_required: str
    settings_key: str | None
    exclusive_keys: tuple[str, ...]
    host_watchdog: bool
    no_watchdog: str
    parse_settings: Callable[..., Any]
    connect: Callable[[TurntableSpec, float], Connection[Any]]
    twins: Mapping[str, Callable[[TurntableSpec, float], TableTwin]]


_CONTROLLERS: dict[str, ControllerKind] = {}


def register_controller(kind: ControllerKind) -> ControllerKind:
    """Add a controller kind (its ``name`` and the names of its twins must be new); returns it."""
    taken = set(simulated_controller_names())
    if kind.name in _CONTROLLERS or taken & set(kind.twins):
        raise ValueError(f"controller {kind.name!r} or one of its twins {sorted(kind.twins)} is already registered")
    _CONTROLLERS[kind.name] = kind
    return kind


def unregister_controller(name: str) -> None:
    """Remove a controller kind (tests that register a toy one)."""
    _CONTROLLERS.pop(name, None)


def controller_names() -> list[str]:
    """The ``turntable.driver`` names of real controllers, in registration order."""
    return list(_CONTROLLERS)


def simulated_controller_names() -> list[str]:
    """The ``simulation.controller`` names, in registration order."""
    return [n for k in _CONTROLLERS.values() for n in k.twins]


def controller(name: str) -> ControllerKind:
    """The controller kind of a real ``turntable.driver`` name (KeyError if none: the loader checks choices)."""
    return _CONTROLLERS[name]


def simulated_controller(sim_name: str) -> ControllerKind:
    """The controller kind a simulated bench's ``simulation.controller`` names."""
    for k in _CONTROLLERS.values():
        if sim_name in k.twins:
            return k
    raise KeyError(sim_name)


def controller_of(spec: TurntableSpec) -> ControllerKind:
    """The controller kind of a loaded turntable section (real driver, or the simulator's controller)."""
    return simulated_controller(spec.sim_controller) if spec.driver == SIMULATED else controller(spec.driver)


def simulated_twin(spec: TurntableSpec, loopback_min_watchdog: float) -> TableTwin:
    """The simulated controller a simulated bench's turntable section names (``simulation.controller``)."""
    return simulated_controller(spec.sim_controller).twins[spec.sim_controller](spec, loopback_min_watchdog)


SIMULATED = "sim"
"""The driver name of a simulated table or unit (``turntable.driver: sim``, ``unit.driver: sim``)."""


# ---- inertial units ----------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class UnitKind:
    """An inertial-unit link a bench can name (``unit.driver``); the simulated unit is :data:`SIMULATED`.

    ``connect(config, raw_sink, raw_name, timeout) -> Connection`` opens the real unit.
    """

    name: str
    title: str
    address_example: str
    connect: Callable[..., Connection[Any]]


_UNITS: dict[str, UnitKind] = {}


def register_unit(kind: UnitKind) -> UnitKind:
    """Add a unit kind (its name must be new); returns it."""
    if kind.name in _UNITS or kind.name == SIMULATED:
        raise ValueError(f"unit driver {kind.name!r} is already registered")
    _UNITS[kind.name] = kind
    return kind


def unit_names() -> list[str]:
    """The ``unit.driver`` names (the simulated unit first)."""
    return [SIMULATED, *_UNITS]


def unit(name: str) -> UnitKind:
    """The unit kind of a real ``unit.driver`` name."""
    return _UNITS[name]


# ---- auxiliary devices -----------------------------------------------------------------------------------------


@dataclass(frozen=True)
class AuxiliaryKind:
    """An auxiliary device a bench can name under ``auxiliary:`` (a temperature chamber, a thermometer, …).

    Attributes
    ----------
    name : str
        The ``driver`` value of its ``auxiliary.<device>`` section.
    parse : callable
        ``(section, smap, path) -> settings`` (a frozen dataclass, SI): the section's keys other than
        ``driver``; errors through ``smap.error(path + (key,), message)`` (file:line and the fix).
    connect : callable or None
        ``(settings, timeout) -> drivers.connect.Connection`` whose driver is a
        :class:`drivers.protocols.Readable` (or ``Settable``); None: simulated only.
    twin : callable or None
        ``(world, settings) -> (device, closers)``: the device on the simulated world (None: hardware only).
    title : str
        What it is, for messages.
    """

    name: str
    parse: Callable[[Mapping[str, Any], SourceMap, KeyPath], Any]
    connect: Callable[[Any, float], Connection[Any]] | None = None
    twin: Callable[[SimulatedWorld, Any], tuple[Readable, list[Callable[[], None]]]] | None = None
    title: str = ""


_AUXILIARY: dict[str, AuxiliaryKind] = {}


def register_auxiliary(kind: AuxiliaryKind) -> AuxiliaryKind:
    """Add an auxiliary device kind (its name must be new); returns it."""
    if kind.name in _AUXILIARY:
        raise ValueError(f"auxiliary device driver {kind.name!r} is already registered")
    _AUXILIARY[kind.name] = kind
    return kind


def unregister_auxiliary(name: str) -> None:
    """Remove an auxiliary device kind (tests that register a toy one)."""
    _AUXILIARY.pop(name, None)


def auxiliary_names() -> list[str]:
    """The registered auxiliary device drivers."""
    return list(_AUXILIARY)


def auxiliary(name: str) -> AuxiliaryKind:
    """The auxiliary device kind of a ``driver`` name."""
    return _AUXILIARY[name]


# ---- the built-in kinds ------------------------------------------------------------------------------------------

DEFAULT_TIMEOUT_S = 2.0
"""Reply time-out of every device link opened from a bench file, s."""


def acl_options(tt: Any) -> dict[str, Any]:
    """The ACL driver's settings and tolerances from a bench's turntable section."""
    return {
        "settings": tt.acl,
        "position_tolerance": tt.position_tolerance,
        "settle_time": tt.in_position_time,
        "rate_tolerance": tt.rate_tolerance,
    }


def _acl_section(
    d: Mapping[str, Any] | None, smap: SourceMap, p: KeyPath, resource: str | None, simulated: bool
) -> AclSettings:
    """The ``turntable.acl`` section: the open points of the ACUTROL command language
    (docs/protocols/acutrol-acl.md)."""
    d = d or {}
    check_keys(
        d,
        smap,
        p,
        ["reply_profile", "mode_reply", "decimals", "axes", "full_scale_deg", "time_variable", "time_scale_s",
         "error_queue", "open_interlocks_at_end"],
    )  # fmt: skip
    profile = get_str(d, smap, p, "reply_profile", default_profile(resource or ""), choices=["gpib", "tcp"])
    axes: tuple[int, ...] = (1, 2, 3)
    if d.get("axes") is not None:
        ad = get_mapping(d["axes"], smap, p + ("axes",))
        check_keys(ad, smap, p + ("axes",), list(AXIS_NAMES))
        axes = tuple(_int(ad, smap, p + ("axes",), n, i + 1, 1, 99) for i, n in enumerate(AXIS_NAMES))
        if len(set(axes)) != 3:
            raise smap.error(p + ("axes",), f"outer, middle and inner need three different axis numbers, got {axes}")
    tv = d.get("time_variable")
    if tv is None:
        time_variable = SIM_TIME_VARIABLE if simulated else None
    else:
        time_variable = _int(d, smap, p, "time_variable", 0, 0, 99999)
    oi = d.get("open_interlocks_at_end", False)
    if not isinstance(oi, bool):
        raise smap.error(p + ("open_interlocks_at_end",), f"expected true or false, got {oi!r}")
    return AclSettings(
        reply_profile=profile,  # type: ignore[arg-type]
        mode_reply=get_str(d, smap, p, "mode_reply", "letter", choices=["letter", "word"]),  # type: ignore[arg-type]
        decimals=_int(d, smap, p, "decimals", 4, 0, 12),
        axes=axes,  # type: ignore[arg-type]
        full_scale_deg=get_number(
            d, smap, p, "full_scale_deg", 360.0, minimum=0, exclusive_minimum=True, maximum=36000
        ),
        time_variable=time_variable,
        time_scale_s=get_number(d, smap, p, "time_scale_s", 0.001, minimum=0, exclusive_minimum=True),
        error_queue=get_str(d, smap, p, "error_queue", "QERROR"),
        open_interlocks_at_end=oi,
        source=(
            f"{smap.file}:{smap.line(p + ('reply_profile',))} turntable.acl.reply_profile"
            if "reply_profile" in d
            else f"{smap.file}:{smap.line(p[:-1] + ('resource',))} (the default for turntable.resource)"
        ),
    )


def _acl_settings(
    d: Mapping[str, Any], smap: SourceMap, p: KeyPath, *, link: str | None, simulated: bool, limits: Any
) -> dict[str, Any]:
    ap = p + ("acl",)
    acl_d = get_mapping(d["acl"], smap, ap) if d.get("acl") is not None else None
    acl = _acl_section(acl_d, smap, ap, link, simulated=simulated)
    half = acl.full_scale_deg / 2.0
    for name, lim in zip(AXIS_NAMES, limits, strict=True):
        for key, v in (("position_min_deg", lim.position_min), ("position_max_deg", lim.position_max)):
            if v is not None and abs(math.degrees(v)) > half + 1e-9:
                raise smap.error(
                    p + ("axes", name, key),
                    f"{math.degrees(v):g}° is outside the controller's full-scale range ±{half:g}° (turntable.acl."
                    "full_scale_deg)",
                )
    return {"acl": acl}


def _modbus_settings(
    d: Mapping[str, Any], smap: SourceMap, p: KeyPath, *, link: str | None, simulated: bool, limits: Any
) -> dict[str, Any]:
    modbus_map = _modbus_map(d, smap, p)
    word_order = get_str(d, smap, p, "float_word_order", None, choices=["big", "little"])
    if modbus_map is not None and word_order is not None and word_order != modbus_map.word_order:
        raise smap.error(
            p + ("float_word_order",),
            f"{word_order!r} contradicts the register map {modbus_map.source} (word_order: {modbus_map.word_order}); "
            "remove float_word_order (the map is the authority) or correct the map",
        )
    return {"modbus_map": modbus_map}


def _modbus_map(d: Mapping[str, Any], smap: SourceMap, p: KeyPath) -> Any:
    if d.get("modbus_map") is None:
        return None
    map_path = Path(get_str(d, smap, p, "modbus_map"))
    if not map_path.is_absolute():
        map_path = Path(smap.file).parent / map_path
    if not map_path.is_file():
        raise smap.error(
            p + ("modbus_map",), f"register map file {map_path} not found (a path relative to the bench file)"
        )
    return load_modbus_map(map_path)


def _acl_connect(tt: Any, timeout: float) -> Connection[Any]:
    from drivers import connect  # lazy: pyvisa (--help time)

    conn: Any = connect.acutrol_table(tt.resource, tuple(tt.limits), timeout=timeout, **acl_options(tt))
    conn.where = f"ACUTROL (ACL) at {tt.resource}"
    return conn


def host_port(address: str | None, default_port: int, what: str = "turntable.address") -> tuple[str, int]:
    """``host[:port]`` split (ConfigError-free: ValueError with the message; the caller names the file)."""
    if not address:
        raise ValueError(f"{what} is required for a Modbus TCP table (e.g. '192.168.0.10:502')")
    host, _, port = address.rpartition(":") if ":" in address else (address, "", str(default_port))
    try:
        return host, int(port)
    except ValueError:
        raise ValueError(f"{what} {address!r}: port must be an integer (e.g. '192.168.0.10:502')") from None


def _modbus_connect(tt: Any, timeout: float) -> Connection[Any]:
    from drivers import connect  # lazy: pymodbus (--help time)

    host, port = host_port(tt.address, 502)
    limits = tuple(tt.limits) if getattr(tt, "limits", None) else None
    conn: Any = connect.modbus_table(
        host,
        port,
        word_order=tt.float_word_order,
        register_map=tt.modbus_map,
        limits=limits,
        timeout=timeout,
        rate_tolerance=getattr(tt, "rate_tolerance", None),
    )
    conn.where = f"Modbus TCP {host}:{port}"
    return conn


def _acl_twin(tt: Any, min_watchdog: float) -> TableTwin:
    from drivers.sim.table_twins import AclTwin  # lazy: scipy (--help time)

    return AclTwin(tt.acl, tuple(tt.limits), acl_options(tt))


def _modbus_twin(tt: Any, min_watchdog: float, strict: bool = False) -> TableTwin:
    from drivers.sim.table_twins import ModbusTwin  # lazy: scipy (--help time)

    wd = getattr(tt, "watchdog", None)
    return ModbusTwin(
        tt.float_word_order,
        tt.modbus_map,
        max(float(wd), min_watchdog) if wd else None,
        watchdog_from_power_up=strict,
        rate_tolerance=getattr(tt, "rate_tolerance", None),
    )


def _strict_plc_twin(tt: Any, min_watchdog: float) -> TableTwin:
    """A strict PLC: the Modbus controller whose watchdog runs from power-up, not from the first heartbeat."""
    return _modbus_twin(tt, min_watchdog, strict=True)


def _serial_connect(un: Any, fmt: Any, timeout: float, raw_sink: Any, raw_name: str) -> Connection[Any]:
    from drivers import connect  # lazy: pyvisa, pymodbus (--help time)

    baud = int(getattr(un, "baudrate", 921600) or 921600)
    return connect.serial_unit(
        un.address, fmt, un.sample_rate, baudrate=baud, timeout=timeout, raw_sink=raw_sink, raw_name=raw_name
    )


register_controller(
    ControllerKind(
        name="acutrol",
        title="an ACUTROL table (driver 'acutrol' or a simulated ACUTROL)",
        link_key="resource",
        link_required="is required for driver 'acutrol': a VISA resource string, e.g. "
        "'TCPIP0::192.168.53.1::9878::SOCKET', 'GPIB0::1::INSTR' or 'ASRL/dev/ttyS0::INSTR'",
        settings_key="acl",
        exclusive_keys=("acl",),
        host_watchdog=False,
        no_watchdog="the ACUTROL command language has no host heartbeat or watchdog",
        parse_settings=_acl_settings,
        connect=_acl_connect,
        twins={"acutrol": _acl_twin},
    )
)
register_controller(
    ControllerKind(
        name="modbus-tcp",
        title="a Modbus table (driver 'modbus-tcp' or a simulated one)",
        link_key="address",
        link_required="is required for driver 'modbus-tcp' (e.g. '192.168.0.10:502')",
        settings_key=None,
        exclusive_keys=("modbus_map",),
        host_watchdog=True,
        no_watchdog="",
        parse_settings=_modbus_settings,
        connect=_modbus_connect,
        twins={"modbus": _modbus_twin, "modbus-strict": _strict_plc_twin},
    )
)
DEFAULT_SIMULATED_CONTROLLER = simulated_controller_names()[0]
"""The simulated controller of a simulated bench that does not name one (``simulation.controller``)."""

register_unit(UnitKind(name="serial", title="a serial unit", address_example="/dev/ttyUSB0", connect=_serial_connect))


__all__ = [
    "SIMULATED",
    "AuxiliaryKind",
    "ControllerKind",
    "UnitKind",
    "auxiliary",
    "auxiliary_names",
    "controller",
    "controller_names",
    "controller_of",
    "register_auxiliary",
    "register_controller",
    "register_unit",
    "simulated_controller",
    "simulated_controller_names",
    "simulated_twin",
    "unit",
    "unit_names",
]

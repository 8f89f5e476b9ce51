"""Devices by name: the ONE registry of what a bench file can name — turntable controllers, inertial units and
auxiliary devices — with, for each, its settings parser, its connect function and its simulated twin.

A bench file names a device by a string (``turntable.driver: acutrol``, ``simulation.controller: modbus``,
``unit.driver: serial``, a top-level ``chamber:`` section); this module is the only place those strings are
resolved. The bench loader (:mod:`benches.bench_config`) asks it which names exist and parses each device's
own settings through it; the factory (:mod:`benches.factory`) asks it to open the device on hardware
(``connect``) or to build its simulated twin on the one simulated world (``twin``).

Adding a device is a new module and a registration, not an edit of the loader or the factory::

    from benches import devices
    devices.register_controller(devices.ControllerKind(name="my-table", ...))
    devices.register_auxiliary(devices.AuxiliaryKind(key="probe", parse=..., open=...))

(see ``docs/extending.md``; ``tests/test_extending.py`` registers a toy controller and a toy auxiliary device
in test code only). The built-in kinds are registered at the end of this module: the ACUTROL (ACL over VISA),
the Modbus TCP table (and its strict-PLC twin), the Ideal Aerosmith, the serial unit and the temperature
chamber. Connect and twin functions import their drivers when called, so naming a device never loads a driver
library (``tablebench --help`` stays light).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

from analysis.units import DEG
from core.declare import Section, flag, integer, number, text
from core.yaml_source import KeyPath, SourceMap, check_keys, get_mapping, get_str
from core.yaml_source import get_int as _int
from drivers.acutrol import AclTurntable
from drivers.acutrol.settings import AclSettings, default_profile
from drivers.aerosmith import AerosmithTable
from drivers.aerosmith.settings import AerosmithSettings
from drivers.chamber.bench_section import parse_chamber
from drivers.modbus.register_map import load_modbus_map
from drivers.protocols import AXIS_NAMES
from drivers.sim.acl_controller import SIM_TIME_VARIABLE
from drivers.sim.thermal_config import ChamberSim

if TYPE_CHECKING:  # types only: the drivers import pyvisa, pymodbus, scipy (tablebench --help)
    from drivers.connect import Connection
    from drivers.sim.table_twins import TableTwin
    from drivers.sim.world import SimulatedWorld

SIMULATED = "sim"
"""The driver name of a simulated table or unit (``turntable.driver: sim``, ``unit.driver: sim``)."""

DEFAULT_TIMEOUT_S = 2.0
"""Reply time-out of every device link opened from a bench file, s."""


class AddressError(ValueError):
    """A device's address in the bench file cannot be used (the factory names the bench file)."""


# ---- turntable controllers -------------------------------------------------------------------------------------


@dataclass(frozen=True)
class ControllerKind:
    """A turntable controller a bench can name.

    Attributes
    ----------
    name : str
        ``turntable.driver`` of a real bench (``acutrol``, ``modbus-tcp``, ``ideal-aerosmith``).
    twins : mapping
        ``simulation.controller`` name → ``(turntable spec, loopback minimum watchdog s) -> TableTwin``: the
        simulated controllers speaking this protocol (:mod:`drivers.sim.table_twins`).
    link_key : {"address", "resource"}
        The ``turntable`` key that says where a real controller is.
    link_required : str
        The message when a real bench lacks ``link_key`` (what to write, with an example).
    own_keys : mapping
        ``turntable`` keys only this controller takes → the message refusing them on another controller.
    no_watchdog : str
        "" if the protocol has a host heartbeat and watchdog; else what has none (the start of the message
        refusing ``heartbeat_period_s`` / ``watchdog_s``).
    parse_settings : callable
        ``(turntable section, smap, path, *, link, simulated) -> dict``: this protocol's own settings as
        :class:`benches.bench_config.TurntableSpec` fields (``acl``, ``modbus_map``, ``aerosmith``; a new
        controller returns ``{"settings": its frozen dataclass}``), read before the axes.
    check_axis : callable or None
        ``(settings fields, axis name, smap, path)``: refuse an axis section the table cannot have.
    check_limits : callable or None
        ``(settings fields, limits, smap, path)``: refuse limits the controller cannot reach.
    connect : callable
        ``(turntable spec, timeout s) -> drivers.connect.Connection`` with ``.where`` (one line naming the
        link): the real controller. An unusable address raises :class:`AddressError`.
    """

    name: str
    link_key: str
    link_required: str
    connect: Callable[[Any, float], Connection[Any]]
    twins: Mapping[str, Callable[[Any, float], TableTwin]] = field(default_factory=dict)
    own_keys: Mapping[str, str] = field(default_factory=dict)
    no_watchdog: str = ""
    parse_settings: Callable[..., dict[str, Any]] | None = None
    check_axis: Callable[[Mapping[str, Any], str, SourceMap, KeyPath], None] | None = None
    check_limits: Callable[[Mapping[str, Any], Any, SourceMap, KeyPath], None] | None = None


_CONTROLLERS: dict[str, ControllerKind] = {}


def register_controller(kind: ControllerKind) -> ControllerKind:
    """Add a controller kind (its name and its twins' names must be new); returns it."""
    if kind.name in _CONTROLLERS or kind.name == SIMULATED or set(simulated_controller_names()) & set(kind.twins):
        raise ValueError(f"controller {kind.name!r} or one of its twins {sorted(kind.twins)} is already registered")
    _CONTROLLERS[kind.name] = kind
    return kind


def unregister_controller(name: str) -> None:
    """Remove a controller kind (a test that registered a toy one)."""
    _CONTROLLERS.pop(name, None)


def controller_names() -> list[str]:
    """The ``turntable.driver`` names of real controllers, in registration order."""
    return list(_CONTROLLERS)


def controllers() -> list[ControllerKind]:
    """Every registered controller kind, in registration order."""
    return list(_CONTROLLERS.values())


def simulated_controller_names() -> list[str]:
    """The ``simulation.controller`` names, in registration order (the first is the default)."""
    return [n for k in _CONTROLLERS.values() for n in k.twins]


def default_simulated_controller() -> str:
    """The simulated controller of a simulated bench that names none (``simulation.controller``)."""
    return simulated_controller_names()[0]


def controller(name: str) -> ControllerKind:
    """The controller kind of a real ``turntable.driver`` name (KeyError if none: the loader checks choices)."""
    return _CONTROLLERS[name]


def simulated_controller(sim_name: str) -> ControllerKind:
    """The controller kind a simulated bench's ``simulation.controller`` names."""
    for k in _CONTROLLERS.values():
        if sim_name in k.twins:
            return k
    raise KeyError(sim_name)


def controller_of(driver: str, sim_controller: str) -> ControllerKind:
    """The controller kind of a turntable section: the real driver's, or the simulated controller's."""
    return simulated_controller(sim_controller) if driver == SIMULATED else controller(driver)


def simulated_twin(tt: Any, loopback_min_watchdog: float) -> TableTwin:
    """The simulated controller a simulated bench's turntable section names (``simulation.controller``)."""
    return simulated_controller(tt.sim_controller).twins[tt.sim_controller](tt, loopback_min_watchdog)


def connect_controller(tt: Any, timeout: float = DEFAULT_TIMEOUT_S) -> Connection[Any]:
    """Open a real bench's turntable (its Connection, ``.where`` naming the link)."""
    return controller(tt.driver).connect(tt, timeout)


# ---- inertial units ----------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class UnitKind:
    """An inertial-unit link a bench can name (``unit.driver``); the simulated unit is :data:`SIMULATED`.

    ``connect(unit spec, frame format, timeout, raw_sink, raw_name) -> Connection`` opens the real unit;
    ``link_required`` is the message when ``unit.address`` is missing.
    """

    name: str
    link_required: str
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


def unit_kind(name: str) -> UnitKind:
    """The unit kind of a real ``unit.driver`` name."""
    return _UNITS[name]


# ---- auxiliary devices -----------------------------------------------------------------------------------------


@dataclass(frozen=True)
class AuxiliaryKind:
    """An auxiliary device a bench can name by a top-level section (``chamber:``, a thermometer, …).

    Attributes
    ----------
    key : str
        The bench file's section, and the device's name on the bench (``Bench.aux[key]``) and in the recording
        (``/aux/<key>``).
    parse : callable
        ``(section, smap, path) -> settings`` (a frozen dataclass, SI); errors through ``smap.error(path +
        (key,), message)`` (file:line and the fix). Declare the keys with :mod:`core.declare`.
    open : callable
        ``(settings, world or None, timeout s) -> (device, closers, line)``: the device on the simulated world
        (a simulated bench: ``world`` given) or on its real link; ``closers`` close what was opened (driver
        first) and must leave the device safe; ``line`` names it for the bench's description.
    simulated : callable
        ``settings -> bool``: the settings name the simulated twin (checked against the bench).
    simulation : callable or None
        ``(SimConfig, settings) -> SimConfig``: what the simulated world needs of the device.
    record_every : float or None
        Bench seconds between readings the runner records under ``/aux/<key>`` (the device is a
        :class:`drivers.protocols.Readable`); None: the runner does not record it (its steps do).
    """

    key: str
    parse: Callable[[Any, SourceMap, KeyPath], Any]
    open: Callable[[Any, SimulatedWorld | None, float], tuple[Any, list[Callable[[], None]], str]]
    simulated: Callable[[Any], bool] = lambda settings: True
    simulation: Callable[[Any, Any], Any] | None = None
    record_every: float | None = None


_AUXILIARY: dict[str, AuxiliaryKind] = {}


def register_auxiliary(kind: AuxiliaryKind) -> AuxiliaryKind:
    """Add an auxiliary device kind (its section key must be new); returns it."""
    if kind.key in _AUXILIARY:
        raise ValueError(f"auxiliary device {kind.key!r} is already registered")
    _AUXILIARY[kind.key] = kind
    return kind


def unregister_auxiliary(key: str) -> None:
    """Remove an auxiliary device kind (a test that registered a toy one)."""
    _AUXILIARY.pop(key, None)


def auxiliary_keys() -> list[str]:
    """The bench sections of the registered auxiliary devices."""
    return list(_AUXILIARY)


def auxiliary(key: str) -> AuxiliaryKind:
    """The auxiliary device kind of a bench section."""
    return _AUXILIARY[key]


# ---- the built-in kinds: the ACUTROL ------------------------------------------------------------------------------


def acl_options(tt: Any) -> dict[str, Any]:
    """The ACL driver's settings and tolerances from a bench's turntable section."""
    return {
        "settings": tt.acl,
        "position_tolerance": tt.position_tolerance,
        "settle_time": tt.in_position_time,
        "rate_tolerance": tt.at_rate_tolerance,
    }


ACL = Section(
    text("reply_profile", choices=["gpib", "tcp"]),
    text("mode_reply", "letter", choices=["letter", "word"]),
    integer("decimals", 4, 0, 12),
    number("full_scale_deg", 360.0, minimum=0, exclusive_minimum=True, maximum=36000),
    number("time_scale_s", 0.001, minimum=0, exclusive_minimum=True),
    text("error_queue", "QERROR"),
    flag("open_interlocks_at_end"),
    order=["reply_profile", "mode_reply", "decimals", "axes", "full_scale_deg", "time_variable", "time_scale_s",
           "error_queue", "open_interlocks_at_end"],
)  # fmt: skip
"""``turntable.acl``: the open points of the ACUTROL command language (docs/protocols/acutrol-acl.md);
``axes`` and ``time_variable`` are read by hand (a sub-section; absent and null mean different things)."""


def _acl(
    d: Mapping[str, Any] | None, smap: SourceMap, p: KeyPath, resource: str | None, simulated: bool
) -> AclSettings:
    """The ``turntable.acl`` section (:data:`ACL`)."""
    d = d or {}
    values = ACL.read(d, smap, p, {"reply_profile": default_profile(resource or "")})
    axes: tuple[int, ...] = (1, 2, 3)
    if d.get("axes") is not None:
        ad = get_mapping(d["axes"], smap, p + ("axes",))
        check_keys(ad, smap, p + ("axes",), list(AXIS_NAMES))
        axes = tuple(_int(ad, smap, p + ("axes",), n, i + 1, 1, 99) for i, n in enumerate(AXIS_NAMES))
        if len(set(axes)) != 3:
            raise smap.error(p + ("axes",), f"outer, middle and inner need three different axis numbers, got {axes}")
    if d.get("time_variable") is None:
        # absent: a simulated controller serves its clock; an explicit null: readings stamped by the host
        time_variable = SIM_TIME_VARIABLE if simulated and "time_variable" not in d else None
    else:
        time_variable = _int(dict(d), smap, p, "time_variable", 0, 0, 99999)
    return AclSettings(
        **values,
        axes=axes,  # type: ignore[arg-type]
        time_variable=time_variable,
        source=(
            f"{smap.file}:{smap.line(p + ('reply_profile',))} turntable.acl.reply_profile"
            if "reply_profile" in d
            else f"{smap.file}:{smap.line(p[:-1] + ('resource',))} (the default for turntable.resource)"
        ),
    )


def _acl_settings(
    d: Mapping[str, Any], smap: SourceMap, p: KeyPath, *, link: str | None, simulated: bool
) -> dict[str, Any]:
    ap = p + ("acl",)
    acl_d = get_mapping(d["acl"], smap, ap) if d.get("acl") is not None else None
    return {"acl": _acl(acl_d, smap, ap, link, simulated=simulated)}


def _acl_limits(fields: Mapping[str, Any], limits: Any, smap: SourceMap, p: KeyPath) -> None:
    half = fields["acl"].full_scale_deg / 2.0
    for name, lim in zip(AXIS_NAMES, limits, strict=True):
        for key, v in (("position_min_deg", lim.position_min), ("position_max_deg", lim.position_max)):
            if v is not None and abs(v / DEG) > half + 1e-9:
                raise smap.error(
                    p + ("axes", name, key),
                    f"{v / DEG:g}° is outside the controller's full-scale range ±{half:g}° (turntable.acl."
                    "full_scale_deg)",
                )


def _acl_connect(tt: Any, timeout: float) -> Connection[Any]:
    from drivers import connect  # lazy: pyvisa (--help time)

    conn: Any = connect.acutrol_table(tt.resource, tuple(tt.limits), timeout=timeout, **acl_options(tt))
    conn.where = f"ACUTROL (ACL) at {tt.resource}"
    return conn


def acl_driver(tt: Any) -> Callable[[Any, Any], Any]:
    """``(transport, clock) -> AclTurntable`` with a bench's settings and tolerances (clock None: the host's)."""

    def build(transport: Any, clock: Any) -> Any:
        extra = {} if clock is None else {"clock": clock}
        return AclTurntable(transport, tuple(tt.limits), **acl_options(tt), **extra)

    return build


def _acl_twin(tt: Any, min_watchdog: float) -> TableTwin:
    from drivers.sim.table_twins import AclTwin  # lazy: scipy (--help time)

    return AclTwin(tt.acl, acl_driver(tt), lambda resource, timeout: _acl_connect_at(resource, tt, timeout))


def _acl_connect_at(resource: str, tt: Any, timeout: float) -> Connection[Any]:
    from drivers import connect  # lazy: pyvisa (--help time)

    return connect.acutrol_table(resource, tuple(tt.limits), timeout=timeout, **acl_options(tt))


# ---- the Modbus TCP table -------------------------------------------------------------------------------------------


def _modbus_settings(
    d: Mapping[str, Any], smap: SourceMap, p: KeyPath, *, link: str | None, simulated: bool
) -> dict[str, Any]:
    modbus_map = None
    if d.get("modbus_map") is not None:
        map_path = Path(get_str(dict(d), smap, p, "modbus_map"))
        if not map_path.is_absolute():
            map_path = Path(smap.file).parent / map_path
        if not map_path.is_file():
            raise smap.error(
                p + ("modbus_map",), f"register map file {map_path} not found (a path relative to the bench file)"
            )
        modbus_map = load_modbus_map(map_path)
    word_order = get_str(dict(d), smap, p, "float_word_order", None, choices=["big", "little"])
    if modbus_map is not None and word_order is not None and word_order != modbus_map.word_order:
        raise smap.error(
            p + ("float_word_order",),
            f"{word_order!r} contradicts the register map {modbus_map.source} (word_order: {modbus_map.word_order}); "
            "remove float_word_order (the map is the authority) or correct the map",
        )
    return {"modbus_map": modbus_map}


def host_port(address: str | None, default_port: int) -> tuple[str, int]:
    """``host[:port]`` of a Modbus TCP table (:class:`AddressError` naming the key and an example)."""
    if not address:
        raise AddressError("turntable.address is required for a Modbus TCP table (e.g. '192.168.0.10:502')")
    host, _, port = address.rpartition(":") if ":" in address else (address, "", str(default_port))
    try:
        return host, int(port)
    except ValueError:
        raise AddressError(
            f"turntable.address {address!r}: port must be an integer (e.g. '192.168.0.10:502')"
        ) from None


def _modbus_connect(tt: Any, timeout: float) -> Connection[Any]:
    from drivers import connect  # lazy: pymodbus (--help time)

    host, port = host_port(tt.address, 502)
    limits = tuple(tt.limits) if getattr(tt, "limits", None) else None
    conn: Any = connect.modbus_table(
        host,
        port,
        word_order=tt.float_word_order,
        register_map=tt.modbus_map,
        limits=limits,  # type: ignore[arg-type]
        timeout=timeout,
        rate_tolerance=tt.at_rate_tolerance,
    )
    conn.where = f"Modbus TCP {host}:{port}"
    return conn


def _modbus_twin(tt: Any, min_watchdog: float, strict: bool = False) -> TableTwin:
    from drivers.sim.table_twins import ModbusTwin  # lazy: scipy (--help time)

    wd = tt.watchdog
    return ModbusTwin(
        tt.float_word_order,  # type: ignore[arg-type]
        tt.modbus_map,
        max(float(wd), min_watchdog) if wd else None,
        watchdog_from_power_up=strict,
        rate_tolerance=tt.at_rate_tolerance,
    )


def _strict_plc_twin(tt: Any, min_watchdog: float) -> TableTwin:
    """A strict PLC: the Modbus controller whose watchdog runs from power-up, not from the first heartbeat."""
    return _modbus_twin(tt, min_watchdog, strict=True)


# ---- the Ideal Aerosmith ------------------------------------------------------------------------------------------

AEROSMITH = Section(
    text("axis", AerosmithSettings.axis, choices=list(AXIS_NAMES)),
    text("command_terminator", AerosmithSettings.command_terminator),
    text("prompt", AerosmithSettings.prompt),
    text("position_query", AerosmithSettings.position_query),
    text("rate_query", AerosmithSettings.rate_query),
)
"""``turntable.aerosmith``: the open points of the Ideal Aerosmith table language
(docs/protocols/ideal-aerosmith.md)."""


def _aerosmith_settings(
    d: Mapping[str, Any], smap: SourceMap, p: KeyPath, *, link: str | None, simulated: bool
) -> dict[str, Any]:
    ap = p + ("aerosmith",)
    section = get_mapping(d["aerosmith"], smap, ap) if d.get("aerosmith") else None
    return {"aerosmith": AEROSMITH.build(AerosmithSettings, section, smap, ap)}


def _aerosmith_axis(fields: Mapping[str, Any], name: str, smap: SourceMap, p: KeyPath) -> None:
    axis = fields["aerosmith"].axis
    if name != axis:
        raise smap.error(
            p + ("axes", name),
            f"an Ideal Aerosmith table has one axis ({axis}, turntable.aerosmith.axis); write '{name}: absent'",
        )


def aerosmith_table(stream: Any, tt: Any, clock: Callable[[], float] | None = None) -> Any:
    """The Ideal Aerosmith driver for a bench's turntable section on an open byte stream (``clock``: the host
    clock, None = the real one)."""
    return AerosmithTable(
        stream,
        tuple(tt.limits),  # type: ignore[arg-type]
        settings=tt.aerosmith,
        position_tolerance=tt.position_tolerance,
        rate_tolerance=tt.rate_tolerance,
        **({"clock": clock} if clock is not None else {}),
    )


def _aerosmith_connect(tt: Any, timeout: float) -> Connection[Any]:
    from drivers import connect  # lazy: pyserial (--help time)

    conn: Any = connect.aerosmith_table(tt.address, lambda stream: aerosmith_table(stream, tt), timeout=timeout)
    conn.where = f"Ideal Aerosmith at {tt.address} (9600 8N1)"
    return conn


def _aerosmith_twin(tt: Any, min_watchdog: float) -> TableTwin:
    from drivers.sim.table_twins import AerosmithTwin  # lazy: scipy (--help time)

    return AerosmithTwin(tt.aerosmith, lambda stream, clock: aerosmith_table(stream, tt, clock))


# ---- the serial unit and the temperature chamber -----------------------------------------------------------------


def _serial_connect(un: Any, fmt: Any, timeout: float, raw_sink: Any, raw_name: str) -> Connection[Any]:
    from drivers import connect  # lazy: pyserial (--help time)

    baud = int(getattr(un, "baudrate", 921600) or 921600)
    return connect.serial_unit(
        un.address, fmt, un.sample_rate, baudrate=baud, timeout=timeout, raw_sink=raw_sink, raw_name=raw_name
    )


def _chamber_open(section: Any, world: Any, timeout: float) -> tuple[Any, list[Callable[[], None]], str]:
    """The bench's chamber: on a simulated bench the world's chamber served in the bench's dialect on loopback,
    else the real link (its own time-out: ``chamber.timeout_s``)."""
    if section.simulated:
        from drivers.sim.chamber_loopback import serve_chamber  # lazy: scipy (--help time)

        assert world is not None
        server, conn = serve_chamber(world, section.config)
        closers = [server.close, conn.close]
    else:
        from drivers.chamber.connect import open_chamber  # lazy: pyserial, pymodbus (--help time)

        conn = open_chamber(section.config)
        closers = [conn.close]
    where = f"chamber: {section.config.dialect} ({'simulated, loopback' if section.simulated else 'real'})"
    return conn.driver, closers, where


def _chamber_simulation(sim: Any, section: Any) -> Any:
    s = section.config.settings
    return replace(sim, chamber=ChamberSim(setpoint_min=s.setpoint_min, setpoint_max=s.setpoint_max))


def _register_builtins() -> None:
    register_controller(
        ControllerKind(
            name="acutrol",
            link_key="resource",
            link_required="is required for driver 'acutrol': a VISA resource string, e.g. "
            "'TCPIP0::192.168.53.1::9878::SOCKET', 'GPIB0::1::INSTR' or 'ASRL/dev/ttyS0::INSTR'",
            own_keys={"acl": "is only for an ACUTROL table (driver 'acutrol' or a simulated ACUTROL)"},
            no_watchdog="the ACUTROL command language",
            parse_settings=_acl_settings,
            check_limits=_acl_limits,
            connect=_acl_connect,
            twins={"acutrol": _acl_twin},
        )
    )
    register_controller(
        ControllerKind(
            name="modbus-tcp",
            link_key="address",
            link_required="is required for driver 'modbus-tcp' (e.g. '192.168.0.10:502')",
            own_keys={"modbus_map": "is only for a Modbus table (driver 'modbus-tcp' or a simulated one)"},
            parse_settings=_modbus_settings,
            connect=_modbus_connect,
            twins={"modbus": _modbus_twin, "modbus-strict": _strict_plc_twin},
        )
    )
    register_controller(
        ControllerKind(
            name="ideal-aerosmith",
            link_key="address",
            link_required="is required for driver 'ideal-aerosmith': the serial port (e.g. '/dev/ttyUSB0', "
            "'COM3' or 'socket://host:port' for a device server; 9600 8N1)",
            own_keys={"aerosmith": "is only for an Ideal Aerosmith table (driver 'ideal-aerosmith' or simulated)"},
            no_watchdog="the Ideal Aerosmith command set",
            parse_settings=_aerosmith_settings,
            check_axis=_aerosmith_axis,
            connect=_aerosmith_connect,
            twins={"ideal-aerosmith": _aerosmith_twin},
        )
    )
    register_unit(
        UnitKind(
            name="serial",
            link_required="is required for driver 'serial' (e.g. '/dev/ttyUSB0')",
            connect=_serial_connect,
        )
    )
    register_auxiliary(
        AuxiliaryKind(
            key="chamber",
            parse=parse_chamber,
            open=_chamber_open,
            simulated=lambda section: bool(section.simulated),
            simulation=_chamber_simulation,
        )
    )


_register_builtins()

__all__ = [
    "SIMULATED",
    "AddressError",
    "AuxiliaryKind",
    "ControllerKind",
    "UnitKind",
    "auxiliary",
    "auxiliary_keys",
    "connect_controller",
    "controller",
    "controller_names",
    "controller_of",
    "controllers",
    "default_simulated_controller",
    "register_auxiliary",
    "register_controller",
    "register_unit",
    "simulated_controller",
    "simulated_controller_names",
    "simulated_twin",
    "unit_kind",
    "unit_names",
    "unregister_auxiliary",
    "unregister_controller",
]

"""Open a bench: build the turntable and inertial-unit drivers a bench file describes.

``open_bench(config)`` returns a :class:`Bench` (context manager) with ``.turntable`` and ``.unit``
(:mod:`drivers.protocols` implementations), ``.world`` (the SimulatedWorld, None on hardware), ``.transport``
and ``.describe()``.

Transports:

``"in-process"`` (simulated bench)
    No bytes, no threads. ``simulation.controller: acutrol`` (default): the real ACL driver
    (:class:`drivers.acutrol.AclTurntable`) talking to the simulated ACUTROL
    (:class:`drivers.sim.acl_controller.AclController`) through an in-memory transport; ``modbus``:
    :class:`drivers.sim.inprocess.SimTurntable` on the world. The unit: ``SimInertialUnit``.
``"loopback"`` (simulated bench)
    The wire-level simulators on 127.0.0.1 (ACL on a TCP socket reached through pyvisa-py's
    ``TCPIP0::127.0.0.1::PORT::SOCKET``, or Modbus TCP; serial unit in polled mode) with the real drivers
    (:mod:`drivers.sim.loopback`). Same seed and commands → the same recording as in-process. The Modbus
    controller's wall-clock watchdog is set to ``max(turntable.watchdog, LOOPBACK_MIN_WATCHDOG_S)`` so a
    stalled CI machine cannot trip it; the world's bench-time watchdog still applies at the configured value.
``"hardware"`` (real bench)
    ``turntable.driver`` "acutrol" (a VISA resource string, opened with pyvisa + pyvisa-py: TCPIP SOCKET,
    GPIB — needs linux-gpib or gpib-ctypes — or ASRL) or "modbus-tcp" (address ``host:port``, default port
    502); ``unit.driver`` "serial" (device/URL at ``unit.baudrate``, free-running stream). The factory opens
    the links (:mod:`drivers.connect`); the drivers never do. :func:`open_table` opens the table alone.

The unit's frame format is ``unit.frame`` with ``unit.frame_options`` (:func:`benches.bench_config.unit_frame_format`):
the serial driver decodes it on hardware and on loopback, where the simulated unit speaks it. With
``unit.keep_raw`` and a ``run_folder``, every byte read from the unit is kept in ``RUN_FOLDER/unit-raw.bin``
(appended on resume); the in-process transport has no byte stream, so nothing is kept there.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, BinaryIO

from core.yaml_source import ConfigError
from drivers import connect
from drivers.acutrol import AclTurntable
from drivers.aerosmith import AerosmithTable
from drivers.chamber.connect import open_chamber
from drivers.protocols import InertialUnit, Turntable
from drivers.sim.acl_controller import AclController
from drivers.sim.acl_server import AclTableServer
from drivers.sim.aerosmith_controller import AerosmithController
from drivers.sim.aerosmith_server import AerosmithTableServer
from drivers.sim.chamber_loopback import serve_chamber
from drivers.sim.inprocess import SimInertialUnit, SimTurntable
from drivers.sim.loopback import Loopback
from drivers.sim.modbus_controller import ModbusTableServer
from drivers.sim.world import SimulatedWorld
from drivers.transport import MessageTransport

from .bench_config import BenchConfig, TurntableSpec, unit_frame_format

log = logging.getLogger(__name__)

TRANSPORTS = ("in-process", "loopback", "hardware")
LOOPBACK_MIN_WATCHDOG_S = 10.0
DEFAULT_TIMEOUT_S = 2.0


@dataclass
class Bench:
    """An open bench. ``close()`` is always safe (idempotent) and closes everything the factory opened."""

    turntable: Turntable
    unit: InertialUnit
    world: SimulatedWorld | None
    transport: str
    description: str
    _closers: list[Callable[[], None]] = field(default_factory=list, repr=False)
    aux: dict[str, Any] = field(default_factory=dict)
    """Named auxiliary devices (``"chamber"``: a :class:`drivers.chamber.base.Chamber`), recorded and commanded by
    the runner's steps."""

    def describe(self) -> str:
        """One line for logs and recordings."""
        return self.description

    def close(self) -> None:
        """Close drivers, then transports/servers, in reverse order of opening; never raises."""
        closers, self._closers = self._closers, []
        for fn in reversed(closers):
            try:
                fn()
            except Exception:
                log.debug("bench close", exc_info=True)

    def __enter__(self) -> Bench:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def _bad(config: BenchConfig, message: str) -> ConfigError:
    return ConfigError(getattr(config, "path", "<bench>"), None, message)


RAW_FILE = "unit-raw.bin"


def _raw_sink(
    config: BenchConfig, run_folder: str | Path | None, closers: list[Callable[[], None]]
) -> tuple[BinaryIO | None, str]:
    """The open raw-stream file when the bench keeps it (``unit.keep_raw``) and a run folder is given."""
    if run_folder is None or not getattr(config.unit, "keep_raw", False):
        return None, ""
    path = Path(run_folder) / RAW_FILE
    try:
        fh = open(path, "ab")  # noqa: SIM115 - closed by the bench
    except OSError as exc:
        raise _bad(config, f"unit.keep_raw: cannot write {path} ({exc.strerror})") from None
    closers.append(fh.close)
    start = fh.seek(0, 2)  # a resumed run appends: say where this session's bytes begin
    return fh, RAW_FILE if start == 0 else f"{RAW_FILE} (this session from byte {start})"


def open_bench(
    config: BenchConfig,
    *,
    seed: int | None = None,
    transport: str | None = None,
    run_folder: str | Path | None = None,
) -> Bench:
    """:func:`_open_table_and_unit`, then the bench's auxiliary devices (its temperature chamber: on a simulated
    bench the world's chamber served in the bench's dialect on loopback, else the real link)."""
    bench = _open_table_and_unit(config, seed=seed, transport=transport, run_folder=run_folder)
    section = getattr(config, "chamber", None)
    if section is None:
        return bench
    try:
        if section.simulated:
            assert bench.world is not None
            server, conn = serve_chamber(bench.world, section.config)
            bench._closers += [server.close, conn.close]
        else:
            conn = open_chamber(section.config)
            bench._closers.append(conn.close)
    except BaseException:
        bench.close()
        raise
    bench.aux["chamber"] = conn.driver
    bench.description += (
        f"; chamber: {section.config.dialect} ({'simulated, loopback' if section.simulated else 'real'})"
    )
    return bench


def _open_table_and_unit(
    config: BenchConfig,
    *,
    seed: int | None = None,
    transport: str | None = None,
    run_folder: str | Path | None = None,
) -> Bench:
    """Open the bench described by ``config`` (a ``benches.bench_config.BenchConfig``).

    Parameters
    ----------
    config : BenchConfig
    seed : int or None
        Simulated benches: seed of the world (None: the bench's default seed).
    transport : {"in-process", "loopback", "hardware"} or None
        None: the simulation section's ``transport`` for simulated benches, "hardware" for real ones.
    run_folder : path or None
        The run folder, where ``unit-raw.bin`` is kept when the bench says ``unit.keep_raw: true``.

    Raises
    ------
    ConfigError
        An impossible combination (e.g. "loopback" for a real bench) or an unusable address.
    LinkError
        A device did not answer.
    """
    transport = _transport(config, transport)
    if transport == "hardware":
        return _open_hardware(config, run_folder)
    return _open_simulated(config, seed, transport, run_folder)


def _transport(config: BenchConfig, transport: str | None) -> str:
    """The transport to open ``config`` with: ``transport`` checked against the bench, or the bench's default
    (a simulated bench's ``simulation.transport``, "hardware" for a real one)."""
    if transport is not None and transport not in TRANSPORTS:
        raise _bad(config, f"transport {transport!r} is not one of {', '.join(TRANSPORTS)}")
    sim = getattr(config, "simulation", None)
    if sim is not None:
        transport = transport or getattr(sim, "transport", "in-process")
        if transport == "hardware":
            raise _bad(config, "this is a simulated bench; transport must be 'in-process' or 'loopback'")
        return transport
    if transport not in (None, "hardware"):
        raise _bad(
            config, f"bench {config.name!r} is a real bench (no simulation section): transport must be 'hardware'"
        )
    return "hardware"


def _open_simulated(
    config: BenchConfig, seed: int | None, transport: str, run_folder: str | Path | None = None
) -> Bench:
    world = SimulatedWorld.from_bench(config, seed)
    tt = config.turntable
    acl = getattr(tt, "sim_controller", "acutrol") == "acutrol"
    aero = getattr(tt, "sim_controller", "") == "ideal-aerosmith"
    if transport == "in-process":
        unit = SimInertialUnit(world)
        if aero:
            table = aerosmith_table(AerosmithController(world, tt.aerosmith).stream(DEFAULT_TIMEOUT_S), tt)
            what = "simulated Ideal Aerosmith (in-memory)"
            return Bench(
                table,
                unit,
                world,
                "in-process",
                f"{config.name}: simulated bench, {what}",
                [table.close, unit.close],
            )
        if acl:
            table: Turntable = acl_turntable(
                AclController(world, tt.acl).transport(DEFAULT_TIMEOUT_S), tt, clock=world.host_time
            )
            what = "simulated ACUTROL (ACL, in-memory)"
        else:
            table, what = SimTurntable(world), "in-process drivers"
        return Bench(
            table,
            unit,
            world,
            "in-process",
            f"{config.name}: simulated bench, {what} (no byte stream: unit.frame "
            f"{getattr(config.unit, 'frame', 'tablebench-v1')} and unit.keep_raw apply over loopback)",
            [table.close, unit.close],
        )
    wd = getattr(tt, "watchdog", None)
    realtime = bool(getattr(config.simulation, "realtime", False))
    closers: list[Callable[[], None]] = []
    raw, raw_name = _raw_sink(config, run_folder, closers)
    try:
        lb = Loopback(
            world,
            dialect="aerosmith" if aero else "acutrol" if acl else "modbus",
            make_acl_table=(
                (lambda transport: acl_turntable(transport, tt, clock=None if realtime else world.host_time))
                if acl
                else None
            ),
            acl=tt.acl,
            make_aerosmith_table=(
                (lambda stream: aerosmith_table(stream, tt, clock=None if realtime else world.host_time))
                if aero
                else None
            ),
            aerosmith=getattr(tt, "aerosmith", None),
            word_order=getattr(tt, "float_word_order", None),
            register_map=getattr(tt, "modbus_map", None),
            watchdog_s=max(float(wd), LOOPBACK_MIN_WATCHDOG_S) if wd else None,
            strict_watchdog=getattr(tt, "sim_controller", "") == "modbus-strict",
            unit_frame=unit_frame_format(config.unit),
            unit_raw=raw,
            unit_raw_name=raw_name,
            realtime=realtime,
        )
    except BaseException:
        for fn in closers:
            fn()
        raise
    return Bench(
        lb.turntable,
        lb.unit,
        world,
        "loopback",
        f"{config.name}: simulated bench, {lb.describe()}",
        [*closers, lb.close],
    )


def _acl_options(tt: TurntableSpec) -> dict[str, Any]:
    """The ACL driver's settings and tolerances from a bench's turntable section."""
    return {
        "settings": tt.acl,
        "position_tolerance": tt.position_tolerance,
        "settle_time": tt.in_position_time,
        "rate_tolerance": tt.at_rate_tolerance,
    }


def aerosmith_table(stream: Any, tt: TurntableSpec, clock: Callable[[], float] | None = None) -> AerosmithTable:
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


def acl_turntable(
    transport: MessageTransport, tt: TurntableSpec, clock: Callable[[], float] | None = None
) -> AclTurntable:
    """The ACL driver for a bench's turntable section on an open transport (settings and tolerances from the bench);
    ``clock``: the host clock (a simulated bench's world clock; None: the host's monotonic clock)."""
    extra = {} if clock is None else {"clock": clock}
    return AclTurntable(transport, tuple(tt.limits), **_acl_options(tt), **extra)  # type: ignore[arg-type]


def _acutrol_connection(resource: str, tt: TurntableSpec) -> connect.Connection[AclTurntable]:
    """Open the VISA ``resource`` and the ACL driver on it, with the bench's turntable settings and tolerances."""
    return connect.acutrol_table(resource, tuple(tt.limits), timeout=DEFAULT_TIMEOUT_S, **_acl_options(tt))  # type: ignore[arg-type]


def _hardware_table(config: BenchConfig) -> connect.Connection[Any]:
    """Open the real turntable (its Connection, with ``.where`` describing it)."""
    tt = config.turntable
    limits = tuple(tt.limits) if getattr(tt, "limits", None) else None
    if tt.driver == "modbus-tcp":
        host, port = _host_port(config, tt.address, 502)
        conn: Any = connect.modbus_table(
            host,
            port,
            word_order=tt.float_word_order,
            register_map=getattr(tt, "modbus_map", None),
            limits=limits,  # type: ignore[arg-type]
            timeout=DEFAULT_TIMEOUT_S,
            rate_tolerance=getattr(tt, "at_rate_tolerance", None),
        )
        conn.where = f"Modbus TCP {host}:{port}"
    elif tt.driver == "acutrol":
        conn = _acutrol_connection(tt.resource, tt)
        conn.where = f"ACUTROL (ACL) at {tt.resource}"
    elif tt.driver == "ideal-aerosmith":
        conn = connect.aerosmith_table(
            tt.address, lambda stream: aerosmith_table(stream, tt), timeout=DEFAULT_TIMEOUT_S
        )
        conn.where = f"Ideal Aerosmith at {tt.address} (9600 8N1)"
    else:
        raise _bad(config, f"turntable.driver {tt.driver!r} needs a simulation section; real: acutrol, modbus-tcp")
    return conn


def open_table(config: BenchConfig, *, seed: int | None = None, transport: str | None = None) -> Bench:
    """Open only the turntable of a bench (``tablebench table``); ``Bench.unit`` is None.

    Simulated benches: the world and its table controller only (in memory, or its server on 127.0.0.1 reached
    over the real wire); the caller advances bench time with ``world.produce``. Real benches: the turntable
    link only. Nothing of the unit is opened.
    """
    transport = _transport(config, transport)
    if transport != "hardware":
        return _open_simulated_table(config, seed, transport)
    conn = _hardware_table(config)
    return Bench(conn.driver, None, None, "hardware", f"{config.name}: table {conn.where}", [conn.close])  # type: ignore[arg-type,attr-defined]


def _open_simulated_table(config: BenchConfig, seed: int | None, transport: str) -> Bench:
    world = SimulatedWorld.from_bench(config, seed)
    tt = config.turntable
    acl = getattr(tt, "sim_controller", "acutrol") == "acutrol"
    aero = getattr(tt, "sim_controller", "") == "ideal-aerosmith"
    closers: list[Callable[[], None]] = []
    ok = False
    try:
        if aero and transport == "in-process":
            table = aerosmith_table(AerosmithController(world, tt.aerosmith).stream(DEFAULT_TIMEOUT_S), tt)
            what = "simulated Ideal Aerosmith (in-memory)"
            closers.append(table.close)
        elif aero:
            asrv = AerosmithTableServer(world, tt.aerosmith)
            closers.append(asrv.close)
            aconn = connect.aerosmith_table(
                asrv.url, lambda stream: aerosmith_table(stream, tt), timeout=DEFAULT_TIMEOUT_S
            )
            closers.insert(0, aconn.close)
            table, what = aconn.driver, f"simulated Ideal Aerosmith over pyserial {asrv.url}"
        elif transport == "in-process":
            if acl:
                table: Turntable = acl_turntable(
                    AclController(world, tt.acl).transport(DEFAULT_TIMEOUT_S), tt, clock=world.host_time
                )
                what = "simulated ACUTROL (ACL, in-memory)"
            else:
                table, what = SimTurntable(world), "simulated table, in-process driver"
            closers.append(table.close)
        elif acl:
            srv = AclTableServer(world, tt.acl)
            closers.append(srv.close)
            conn = _acutrol_connection(srv.resource, tt)
            closers.insert(0, conn.close)
            table, what = conn.driver, f"simulated ACUTROL over pyvisa-py {srv.resource}"
        else:
            wd = getattr(tt, "watchdog", None)
            msrv = ModbusTableServer(
                world,
                word_order=tt.float_word_order,
                register_map=getattr(tt, "modbus_map", None),
                watchdog_s=max(float(wd), LOOPBACK_MIN_WATCHDOG_S) if wd else None,
                watchdog_from_power_up=getattr(tt, "sim_controller", "") == "modbus-strict",
            )
            closers.append(msrv.close)
            mconn = connect.modbus_table(
                "127.0.0.1",
                msrv.port,
                word_order=tt.float_word_order,
                register_map=getattr(tt, "modbus_map", None),
                timeout=DEFAULT_TIMEOUT_S,
                retries=0,
                rate_tolerance=getattr(tt, "at_rate_tolerance", None),
            )
            closers.insert(0, mconn.close)
            table, what = mconn.driver, f"simulated Modbus table on 127.0.0.1:{msrv.port}"
        ok = True
        return Bench(table, None, world, transport, f"{config.name}: {what}", list(reversed(closers)))  # type: ignore[arg-type]
    finally:
        if not ok:
            for fn in closers:
                try:
                    fn()
                except Exception:
                    log.debug("close after failed open", exc_info=True)


def _host_port(config: BenchConfig, address: str | None, default_port: int) -> tuple[str, int]:
    if not address:
        raise _bad(config, "turntable.address is required for a Modbus TCP table (e.g. '192.168.0.10:502')")
    host, _, port = address.rpartition(":") if ":" in address else (address, "", str(default_port))
    try:
        p = int(port)
    except ValueError:
        raise _bad(
            config, f"turntable.address {address!r}: port must be an integer (e.g. '192.168.0.10:502')"
        ) from None
    return host, p


def _open_hardware(config: BenchConfig, run_folder: str | Path | None = None) -> Bench:
    opened: list[connect.Connection[Any]] = []
    closers: list[Callable[[], None]] = []  # the raw-stream file, closed after the drivers
    bench_ok = False
    try:
        opened.append(_hardware_table(config))
        where = opened[0].where  # type: ignore[attr-defined]
        un = config.unit
        if un.driver != "serial":
            raise _bad(config, f"unit.driver {un.driver!r} needs a simulation section; a real unit uses 'serial'")
        if not un.address:
            raise _bad(config, "unit.address is required for a serial unit (e.g. '/dev/ttyUSB0')")
        fmt = unit_frame_format(un)
        raw, raw_name = _raw_sink(config, run_folder, closers)
        baud = int(getattr(un, "baudrate", 921600) or 921600)
        opened.append(
            connect.serial_unit(
                un.address,
                fmt,
                un.sample_rate,
                baudrate=baud,
                timeout=DEFAULT_TIMEOUT_S,
                raw_sink=raw,
                raw_name=raw_name,
            )
        )
        table, unit = opened[0].driver, opened[1].driver
        where_unit = f"unit ({fmt.name}) on {un.address}"
        bench = Bench(
            table,
            unit,
            None,
            "hardware",
            f"{config.name}: table {where}, {where_unit}",
            [*closers, *(c.close for c in opened)],
        )
        bench_ok = True
        return bench
    finally:
        if not bench_ok:
            for c in reversed(opened):
                c.close()
            for fn in reversed(closers):
                fn()

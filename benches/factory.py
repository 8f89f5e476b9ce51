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
    ``turntable.driver`` ``acutrol`` (a VISA resource string, opened with pyvisa + pyvisa-py: TCPIP SOCKET,
    GPIB — needs linux-gpib or gpib-ctypes — or ASRL) or ``modbus-tcp`` (address ``host:port``, default port
    502); ``unit.driver`` ``serial`` (device/URL at ``unit.baudrate``, free-running stream). The factory opens
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
from drivers.protocols import InertialUnit, Turntable
from drivers.sim.inprocess import SimInertialUnit
from drivers.sim.world import SimulatedWorld

from . import devices
from .bench_config import BenchConfig, unit_frame_format

log = logging.getLogger(__name__)

TRANSPORTS = ("in-process", "loopback", "hardware")
LOOPBACK_MIN_WATCHDOG_S = 10.0
DEFAULT_TIMEOUT_S = devices.DEFAULT_TIMEOUT_S


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
    """Named auxiliary devices (the bench section that names each, :mod:`benches.devices`; ``"chamber"``: a
    :class:`drivers.chamber.base.Chamber`), commanded by the runner's steps and, when their kind says so, recorded
    by the runner under ``/aux/<name>``."""
    aux_every: dict[str, float] = field(default_factory=dict)
    """Bench seconds between the runner's recorded readings of each auxiliary device it records."""

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
    """:func:`_open_table_and_unit`, then the bench's auxiliary devices (:mod:`benches.devices`: each kind opens
    its device on the simulated world or on its real link; the temperature chamber is one)."""
    bench = _open_table_and_unit(config, seed=seed, transport=transport, run_folder=run_folder)
    try:
        for key, settings in getattr(config, "auxiliary", {}).items():
            kind = devices.auxiliary(key)
            device, closers, line = kind.open(settings, bench.world, DEFAULT_TIMEOUT_S)
            bench._closers += closers
            bench.aux[key] = device
            if kind.record_every is not None:
                bench.aux_every[key] = float(kind.record_every)
            bench.description += f"; {line}"
    except BaseException:
        bench.close()
        raise
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


def _twin(config: BenchConfig, transport: str) -> Any:
    """The simulated controller the bench names (:mod:`benches.devices`), checked against the transport."""
    twin = devices.simulated_twin(config.turntable, LOOPBACK_MIN_WATCHDOG_S)
    if twin.in_process_only and transport != "in-process":
        raise _bad(config, twin.in_process_only)
    return twin


def _open_simulated(
    config: BenchConfig, seed: int | None, transport: str, run_folder: str | Path | None = None
) -> Bench:
    world = SimulatedWorld.from_bench(config, seed)
    twin = _twin(config, transport)
    if transport == "in-process":
        unit = SimInertialUnit(world)
        table, what = twin.in_process(world, DEFAULT_TIMEOUT_S)
        note = (
            f" (no byte stream: unit.frame {getattr(config.unit, 'frame', 'tablebench-v1')} and unit.keep_raw "
            "apply over loopback)"
            if twin.unit_note
            else ""
        )
        return Bench(
            table,
            unit,
            world,
            "in-process",
            f"{config.name}: simulated bench, {what}{note}",
            [table.close, unit.close],
        )
    from drivers.sim.loopback import Loopback  # lazy: pymodbus, the wire servers (--help time)

    closers: list[Callable[[], None]] = []
    raw, raw_name = _raw_sink(config, run_folder, closers)
    try:
        lb = Loopback(
            world,
            table=twin,
            unit_frame=unit_frame_format(config.unit),
            unit_raw=raw,
            unit_raw_name=raw_name,
            realtime=bool(getattr(config.simulation, "realtime", False)),
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


def _hardware_table(config: BenchConfig) -> connect.Connection[Any]:
    """Open the real turntable (its Connection, with ``.where`` describing it) through the device registry."""
    tt = config.turntable
    if tt.driver not in devices.controller_names():
        raise _bad(
            config,
            f"turntable.driver {tt.driver!r} needs a simulation section; real: {', '.join(devices.controller_names())}",
        )
    try:
        return devices.connect_controller(tt, DEFAULT_TIMEOUT_S)
    except devices.AddressError as exc:
        raise _bad(config, str(exc)) from None


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
    twin = _twin(config, transport)
    closers: list[Callable[[], None]] = []
    ok = False
    try:
        if transport == "in-process":
            table, what = twin.in_process(world, DEFAULT_TIMEOUT_S, alone=True)
            closers.append(table.close)
        else:
            server = twin.serve(world)
            closers.append(server.close)
            conn = twin.connect(server, DEFAULT_TIMEOUT_S, None, alone=True)
            closers.insert(0, conn.close)
            table, what = conn.driver, twin.describe_alone(server)
        ok = True
        return Bench(table, None, world, transport, f"{config.name}: {what}", list(reversed(closers)))  # type: ignore[arg-type]
    finally:
        if not ok:
            for fn in closers:
                try:
                    fn()
                except Exception:
                    log.debug("close after failed open", exc_info=True)


def _open_hardware(config: BenchConfig, run_folder: str | Path | None = None) -> Bench:
    opened: list[connect.Connection[Any]] = []
    closers: list[Callable[[], None]] = []  # the raw-stream file, closed after the drivers
    bench_ok = False
    try:
        opened.append(_hardware_table(config))
        where = opened[0].where  # type: ignore[attr-defined]
        un = config.unit
        if un.driver not in devices.unit_names()[1:]:
            raise _bad(config, f"unit.driver {un.driver!r} needs a simulation section; a real unit uses 'serial'")
        if not un.address:
            raise _bad(config, "unit.address is required for a serial unit (e.g. '/dev/ttyUSB0')")
        fmt = unit_frame_format(un)
        raw, raw_name = _raw_sink(config, run_folder, closers)
        opened.append(devices.unit_kind(un.driver).connect(un, fmt, DEFAULT_TIMEOUT_S, raw, raw_name))
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

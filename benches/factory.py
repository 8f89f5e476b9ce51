"""Open a bench: build the turntable and inertial-unit drivers a bench file describes.

``open_bench(config)`` returns a :class:`Bench` (context manager) with ``.turntable`` and ``.unit``
(:mod:`drivers.protocols` implementations), ``.world`` (the SimulatedWorld, None on hardware), ``.transport``
and ``.describe()``.

Transports:

``"in-process"`` (simulated bench)
    :class:`drivers.sim.inprocess.SimTurntable` / ``SimInertialUnit`` directly on the world (fastest).
``"loopback"`` (simulated bench)
    The wire-level simulators on 127.0.0.1 (Modbus TCP, or ASCII when ``turntable.driver`` is
    ``"ascii-serial"``; serial unit in polled mode) with the real drivers (:mod:`drivers.sim.loopback`). Same
    seed and commands → bit-identical samples to in-process. The controller's wall-clock watchdog is set to
    ``max(turntable.watchdog, LOOPBACK_MIN_WATCHDOG_S)`` so a stalled CI machine cannot trip it; the world's
    bench-time watchdog still applies at the configured value.
``"hardware"`` (real bench)
    ``turntable.driver`` "modbus-tcp" (address ``host:port``, default port 502) or "ascii-serial" (a pyserial
    URL or device, e.g. ``/dev/ttyS0`` or ``socket://host:9888``); ``unit.driver`` "serial" (device/URL at
    ``unit.baudrate``, free-running stream). The factory opens the clients; the drivers never do.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field
from typing import Any

from core.yaml_source import ConfigError
from drivers import connect
from drivers.protocols import InertialUnit, Turntable
from drivers.sim.inprocess import SimInertialUnit, SimTurntable
from drivers.sim.loopback import Loopback
from drivers.sim.world import SimulatedWorld

from .bench_config import BenchConfig

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
    _closers: list[Any] = field(default_factory=list, repr=False)

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


def open_bench(config: BenchConfig, *, seed: int | None = None, transport: str | None = None) -> Bench:
    """Open the bench described by ``config`` (a ``benches.bench_config.BenchConfig``).

    Parameters
    ----------
    config : BenchConfig
    seed : int or None
        Simulated benches: seed of the world (None: the bench's default seed).
    transport : {"in-process", "loopback", "hardware"} or None
        None: the simulation section's ``transport`` for simulated benches, "hardware" for real ones.

    Raises
    ------
    ConfigError
        An impossible combination (e.g. "loopback" for a real bench) or an unusable address.
    LinkError
        A device did not answer.
    """
    if transport is not None and transport not in TRANSPORTS:
        raise _bad(config, f"transport {transport!r} is not one of {', '.join(TRANSPORTS)}")
    sim = getattr(config, "simulation", None)
    if sim is not None:
        transport = transport or getattr(sim, "transport", "in-process")
        if transport == "hardware":
            raise _bad(config, "this is a simulated bench; transport must be 'in-process' or 'loopback'")
        return _open_simulated(config, seed, transport)
    transport = transport or "hardware"
    if transport != "hardware":
        raise _bad(
            config, f"bench {config.name!r} is a real bench (no simulation section): transport must be 'hardware'"
        )
    return _open_hardware(config)


def _open_simulated(config: BenchConfig, seed: int | None, transport: str) -> Bench:
    world = SimulatedWorld.from_bench(config, seed)
    if transport == "in-process":
        table, unit = SimTurntable(world), SimInertialUnit(world)
        return Bench(
            table,
            unit,
            world,
            "in-process",
            f"{config.name}: simulated bench, in-process drivers",
            [table.close, unit.close],
        )
    tt = config.turntable
    dialect = "ascii" if getattr(tt, "driver", "sim") == "ascii-serial" else "modbus"
    wd = getattr(tt, "watchdog", None)
    lb = Loopback(
        world,
        dialect=dialect,
        word_order=getattr(tt, "float_word_order", "big") or "big",
        watchdog_s=max(float(wd), LOOPBACK_MIN_WATCHDOG_S) if wd else None,
    )
    return Bench(
        lb.turntable, lb.unit, world, "loopback", f"{config.name}: simulated bench, {lb.describe()}", [lb.close]
    )


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


def _open_hardware(config: BenchConfig) -> Bench:
    opened: list[connect.Connection[Any]] = []
    bench_ok = False
    try:
        tt = config.turntable
        limits = tuple(tt.limits) if getattr(tt, "limits", None) else None
        if tt.driver == "modbus-tcp":
            host, port = _host_port(config, tt.address, 502)
            word_order = getattr(tt, "float_word_order", "big") or "big"
            opened.append(
                connect.modbus_table(host, port, word_order=word_order, limits=limits, timeout=DEFAULT_TIMEOUT_S)
            )
            where = f"Modbus TCP {host}:{port}"
        elif tt.driver == "ascii-serial":
            if not tt.address:
                raise _bad(config, "turntable.address is required for an ASCII table (e.g. '/dev/ttyS0')")
            opened.append(connect.ascii_table(tt.address, limits=limits, timeout=DEFAULT_TIMEOUT_S))
            where = f"ASCII on {tt.address}"
        else:
            raise _bad(
                config, f"turntable.driver {tt.driver!r} needs a simulation section; real: modbus-tcp, ascii-serial"
            )
        un = config.unit
        if un.driver != "serial":
            raise _bad(config, f"unit.driver {un.driver!r} needs a simulation section; a real unit uses 'serial'")
        if not un.address:
            raise _bad(config, "unit.address is required for a serial unit (e.g. '/dev/ttyUSB0')")
        baud = int(getattr(un, "baudrate", 921600) or 921600)
        opened.append(
            connect.serial_unit(un.address, un.scale, un.sample_rate, baudrate=baud, timeout=DEFAULT_TIMEOUT_S)
        )
        table, unit = opened[0].driver, opened[1].driver
        closers = [c.close for c in opened]
        bench = Bench(table, unit, None, "hardware", f"{config.name}: table {where}, unit on {un.address}", closers)
        bench_ok = True
        return bench
    finally:
        if not bench_ok:
            for c in reversed(opened):
                c.close()

"""Turntable behaviour over Modbus TCP (both word orders) against the simulated controller on loopback,
compared with the in-process driver on an identically seeded world (ACL: tests/drivers/test_wire_acutrol.py)."""

from __future__ import annotations

import math
import time

import numpy as np
import pytest
from pymodbus.client import ModbusTcpClient

from drivers import connect
from drivers.modbus import registers as reg
from drivers.modbus.table import ModbusTurntable
from drivers.protocols import AxisLimits, AxisMode, FaultCode, LinkError, TableError, TableStatus, Turntable
from drivers.sim.inprocess import SimTurntable
from drivers.sim.modbus_controller import ModbusTableServer
from tests.drivers.wire_support import LIMITS, make_world

DIALECTS = ["modbus-big", "modbus-little"]


class Counting:
    """Proxy that counts calls of the transport's sending methods (to prove nothing was sent)."""

    def __init__(self, inner, methods):
        self._inner = inner
        self.calls = 0
        self._methods = set(methods)

    def __getattr__(self, name):
        attr = getattr(self._inner, name)
        if name in self._methods:

            def wrapped(*a, **k):
                self.calls += 1
                return attr(*a, **k)

            return wrapped
        return attr

    def __setattr__(self, name, value):
        if name in ("_inner", "calls", "_methods"):
            object.__setattr__(self, name, value)
        else:
            setattr(self._inner, name, value)


@pytest.fixture
def wire():
    """Factory: (world, server, turntable, transport proxy) for a dialect; all closed afterwards."""
    opened = []

    def make(dialect, seed=1, watchdog_s=None, limits=None):
        world = make_world(seed)
        order = dialect.split("-")[1]
        srv = ModbusTableServer(world, word_order=order, watchdog_s=watchdog_s)
        opened.append(srv.close)
        conn = connect.modbus_table(
            "127.0.0.1",
            srv.port,
            word_order=order,
            limits=limits,
            timeout=0.5,
            retries=0,
            wrap=lambda client: Counting(client, {"write_registers", "write_register"}),
        )
        opened.append(conn.close)
        return world, srv, conn.driver, conn.transport

    yield make
    for fn in reversed(opened):
        fn()


def _advance(world, table, n: int) -> None:
    """Advance bench time by n samples, feeding the heartbeat every 200 samples (as the runner does)."""
    for k in range(0, n, 200):
        world.produce(min(200, n - k))
        table.heartbeat()


def _close(dialect: str) -> dict:
    return {"rtol": 0, "atol": 0}  # Modbus float64: bit for bit


@pytest.mark.parametrize("order", ["big", "little"])
def test_register_codec_matches_pymodbus(order):
    vals = [math.pi, -1e-300, 12345.678901234567, math.nan, 0.0]
    regs = reg.pack_float64(vals, order)
    assert len(regs) == 20 and all(0 <= r <= 0xFFFF for r in regs)
    ref = [
        ModbusTcpClient.convert_from_registers(regs[i : i + 4], ModbusTcpClient.DATATYPE.FLOAT64, word_order=order)
        for i in range(0, 20, 4)
    ]
    got = reg.unpack_float64(regs, order)
    np.testing.assert_array_equal(got, ref)
    np.testing.assert_array_equal(got, vals)
    r32 = reg.pack_float32([1.5, -2.25], order)
    assert r32 == ModbusTcpClient.convert_to_registers([1.5, -2.25], ModbusTcpClient.DATATYPE.FLOAT32, word_order=order)
    with pytest.raises(ValueError, match="word order"):
        reg.pack_float64(1.0, "middle")  # type: ignore[arg-type]


@pytest.mark.parametrize("dialect", DIALECTS)
def test_limits_readback(wire, dialect):
    world, _srv, table, _proxy = wire(dialect)
    assert isinstance(table, Turntable)
    for got, want in zip(table.limits(), world.table_limits(), strict=True):
        np.testing.assert_allclose(got.rate_max, want.rate_max, **_close(dialect))
        np.testing.assert_allclose(got.accel_max, want.accel_max, **_close(dialect))
        assert (got.position_min is None) == (want.position_min is None)
        assert (got.position_max is None) == (want.position_max is None)


@pytest.mark.parametrize("dialect", DIALECTS)
def test_same_commands_same_states_as_in_process(wire, dialect):
    world, _srv, table, _proxy = wire(dialect, seed=5)
    ref_world = make_world(5)
    ref = SimTurntable(ref_world)
    target = [math.radians(20.0), math.radians(-30.0), math.radians(100.0)]
    for t in (table, ref):
        t.move_to(target)
    _advance(world, table, 4000)
    _advance(ref_world, ref, 4000)
    s, r = table.read_state(), ref.read_state()
    assert s.time == r.time and s.status == r.status and s.modes == r.modes
    assert s.status & TableStatus.IN_POSITION
    np.testing.assert_allclose(s.angles, r.angles, **_close(dialect))
    np.testing.assert_allclose(s.angles, target, atol=1e-4)
    for t in (table, ref):
        t.spin(2, math.radians(-15.0))
    _advance(world, table, 1500)
    _advance(ref_world, ref, 1500)
    s, r = table.read_state(), ref.read_state()
    assert s.modes[2] == AxisMode.RATE and s.status == r.status
    np.testing.assert_allclose(s.rates, r.rates, **_close(dialect))
    np.testing.assert_allclose(s.rates[2], math.radians(-15.0), rtol=1e-3)
    table.stop()
    ref.stop()
    _advance(world, table, 1500)
    _advance(ref_world, ref, 1500)
    s = table.read_state()
    assert s.modes == (AxisMode.STOP,) * 3 and np.all(np.abs(s.rates) < 1e-6)


@pytest.mark.parametrize("dialect", DIALECTS)
def test_out_of_limit_commands_refused_before_sending(wire, dialect):
    world, _srv, table, proxy = wire(dialect)
    before = proxy.calls
    with pytest.raises(TableError, match="nothing was sent"):
        table.move_to([0.0, math.radians(200.0), 0.0])  # middle axis limited to ±180°
    with pytest.raises(TableError, match="nothing was sent"):
        table.spin(0, LIMITS[0].rate_max * 1.01)
    with pytest.raises(TableError, match="axis must be"):
        table.spin(3, 0.1)
    with pytest.raises(TableError, match="3 gimbal angles"):
        table.move_to([0.0, 0.0])
    assert proxy.calls == before
    assert world.table_state().modes == (AxisMode.POSITION,) * 3 and world.samples_produced == 0


@pytest.mark.parametrize("dialect", DIALECTS)
def test_controller_checks_limits_itself(wire, dialect):
    loose = tuple(AxisLimits(rate_max=100.0, accel_max=100.0) for _ in range(3))
    world, _srv, table, proxy = wire(dialect, limits=loose)
    with pytest.raises(TableError, match="refused"):
        table.move_to([0.0, math.radians(200.0), 0.0])
    with pytest.raises(TableError, match="refused"):
        table.spin(1, LIMITS[1].rate_max * 1.5)
    assert proxy.calls > 0
    world.produce(100)
    assert np.all(world.table_state().rates == 0)


@pytest.mark.parametrize("dialect", DIALECTS)
def test_fault_reported_and_commands_refused_until_cleared(wire, dialect):
    world, _srv, table, _proxy = wire(dialect)
    table.spin(2, 0.5)
    world.produce(500)
    world.inject_fault(FaultCode.STALL)
    s = table.read_state()
    assert s.status & TableStatus.FAULT and s.fault_code == FaultCode.STALL
    with pytest.raises(TableError, match="STALL|refused"):
        table.spin(2, 0.5)
    table.clear_fault()
    assert not table.read_state().status & TableStatus.FAULT
    table.move_to([0.1, 0.1, 0.1])  # accepted again


@pytest.mark.parametrize("dialect", DIALECTS)
def test_wall_clock_watchdog_stops_the_table(wire, dialect):
    world, srv, table, _proxy = wire(dialect, watchdog_s=0.2)
    table.heartbeat()
    table.spin(0, 0.5)
    _advance(world, table, 1000)
    assert table.read_state().modes[0] == AxisMode.RATE
    n0 = world.samples_produced
    deadline = time.monotonic() + 3.0
    while not srv.watchdog_tripped and time.monotonic() < deadline:
        time.sleep(0.02)  # no heartbeat
    assert srv.watchdog_tripped and world.samples_produced == n0  # tripped on wall time, not bench time
    world.produce(3000)
    s = table.read_state()
    assert s.status & TableStatus.WATCHDOG and s.status & TableStatus.FAULT
    assert s.fault_code == FaultCode.COMMUNICATION_LOST
    assert np.all(np.abs(s.rates) < 1e-6)
    with pytest.raises(TableError):
        table.spin(0, 0.5)
    table.clear_fault()
    assert not table.read_state().status & TableStatus.WATCHDOG


@pytest.mark.parametrize("dialect", DIALECTS)
def test_heartbeats_keep_the_watchdog_quiet(wire, dialect):
    world, srv, table, _proxy = wire(dialect, watchdog_s=0.5)
    table.spin(0, 0.5)
    t_end = time.monotonic() + 0.8
    while time.monotonic() < t_end:
        table.heartbeat()
        time.sleep(0.05)
    assert not srv.watchdog_tripped
    assert table.read_state().modes[0] == AxisMode.RATE


@pytest.mark.parametrize("dialect", DIALECTS)
def test_dropped_connection_is_a_link_error_and_stops_the_table(wire, dialect):
    world, srv, table, _proxy = wire(dialect)
    table.spin(1, 0.3)
    srv.drop_clients()
    t0 = time.monotonic()
    with pytest.raises(LinkError):
        table.read_state()
    assert time.monotonic() - t0 < 1.0
    deadline = time.monotonic() + 2.0
    while world.table_state().modes[1] != AxisMode.STOP and time.monotonic() < deadline:
        time.sleep(0.02)
    assert world.table_state().modes[1] == AxisMode.STOP  # the controller stopped the table on disconnect


def test_word_order_mismatch_is_reported_clearly():
    world = make_world(1)
    with ModbusTableServer(world, word_order="little") as srv:
        client = ModbusTcpClient("127.0.0.1", port=srv.port, timeout=0.5, retries=0)
        assert client.connect()
        try:
            with pytest.raises(LinkError, match="check float_word_order"):
                ModbusTurntable(client, word_order="big")
        finally:
            client.close()

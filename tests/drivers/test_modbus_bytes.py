"""Exact register traffic of the Modbus table driver, written from the shipped register map
(drivers/modbus/maps/tablebench.yaml), not from the simulator: every write and read is scripted with the
registers the map prescribes, as Modbus request PDUs checked byte for byte by the one transcript helper
(tests/drivers/transcript.py); floats packed here with struct (IEEE-754 float64, 16-bit words big-endian,
word order big or little)."""

from __future__ import annotations

import math
import struct

import numpy as np
import pytest

from drivers.modbus.table import ModbusTurntable
from drivers.protocols import AxisLimits, AxisMode, FaultCode, LinkError, TableError, TableStatus
from tests.drivers.transcript import ModbusTranscript, exception, read_input, write_registers

LIMITS = tuple(AxisLimits(rate_max=math.radians(200), accel_max=math.radians(50)) for _ in range(3))


def f64(values, order):
    out = []
    for v in values:
        words = list(struct.unpack(">4H", struct.pack(">d", v)))
        out += words if order == "big" else words[::-1]
    return out


def client(pairs):
    return ModbusTranscript(pairs)


@pytest.mark.parametrize("order", ["big", "little"])
def test_move_spin_stop_heartbeat_clear(order):
    a = [math.radians(10), math.radians(-20), math.radians(30)]
    c = client(
        [
            write_registers(0, f64(a, order)),  # POSITION_SETPOINT (HR 0..11)
            write_registers(25, [1]),  # COMMAND = MOVE
            write_registers(12 + 8, f64([math.radians(-15)], order)),  # RATE_SETPOINT of the inner axis
            write_registers(24, [2, 2]),  # COMMAND_AXIS = 2, COMMAND = SPIN
            write_registers(25, [3]),  # STOP
            write_registers(26, [1]),  # HEARTBEAT counter
            write_registers(27, [1]),  # FAULT_RESET
        ]
    )
    t = ModbusTurntable(c, word_order=order, limits=LIMITS)
    t.move_to(a)
    t.spin(2, math.radians(-15))
    t.stop()
    t.heartbeat()
    t.clear_fault()
    assert not c.script


@pytest.mark.parametrize("order", ["big", "little"])
def test_read_state_is_one_request(order):
    regs = f64([12.5, 0.1, 0.2, 0.3, 0.0, 0.0, -0.5], order)
    regs += [int(TableStatus.AT_RATE | TableStatus.MOVING | TableStatus.REMOTE), 0, 1, 1, 2, 0, 7]
    c = client([read_input(0, regs)])
    s = ModbusTurntable(c, word_order=order, limits=LIMITS).read_state()
    assert s.time == 12.5 and s.modes == (AxisMode.POSITION, AxisMode.POSITION, AxisMode.RATE)
    np.testing.assert_array_equal(s.angles, [0.1, 0.2, 0.3])
    assert s.rates[2] == -0.5 and s.status & TableStatus.AT_RATE


def test_fault_and_refusal_and_link_errors():
    regs = f64([1.0, 0, 0, 0, 0, 0, 0], "big") + [int(TableStatus.FAULT), int(FaultCode.STALL), 0, 0, 0, 0, 0]
    c = client(
        [
            read_input(0, regs),
            write_registers(0, f64([0.0, 0.0, 0.0], "big")),
            (write_registers(25, [1])[0], exception(16, 4)),  # device failure: a fault is latched
            read_input(28, [8, int(FaultCode.STALL), 0, 0, 0, int(FaultCode.STALL)]),
            (read_input(0, [0] * 35)[0], None),
        ]
    )
    t = ModbusTurntable(c, limits=LIMITS)
    s = t.read_state()
    assert s.status & TableStatus.FAULT and s.fault_code == FaultCode.STALL
    with pytest.raises(TableError, match="STALL"):
        t.move_to([0.0, 0.0, 0.0])
    with pytest.raises(LinkError, match="no response"):
        t.read_state()
    with pytest.raises(TableError, match="nothing was sent"):
        t.spin(0, math.radians(201))
    assert not c.script

"""Exact register traffic of the Modbus table driver, written from the shipped register map
(drivers/modbus/maps/tablebench.yaml), not from the simulator: every write and read is scripted with the
registers the map prescribes, floats packed here with struct (IEEE-754 float64, 16-bit words big-endian,
word order big or little)."""

from __future__ import annotations

import math
import struct

import numpy as np
import pytest

from drivers.modbus.table import ModbusTurntable
from drivers.protocols import AxisLimits, AxisMode, FaultCode, LinkError, TableError, TableStatus

LIMITS = tuple(AxisLimits(rate_max=math.radians(200), accel_max=math.radians(50)) for _ in range(3))


def f64(values, order):
    out = []
    for v in values:
        words = list(struct.unpack(">4H", struct.pack(">d", v)))
        out += words if order == "big" else words[::-1]
    return out


class Reply:
    def __init__(self, registers=None, exception_code=None):
        self.registers = registers or []
        self.exception_code = exception_code

    def isError(self):  # noqa: N802 - pymodbus API
        return self.exception_code is not None


class ScriptedClient:
    """A pymodbus-like client that checks each request against a script (function, address, payload/count)."""

    def __init__(self, script):
        self.script = list(script)

    def _next(self, kind, address, payload, device_id):
        assert device_id == 1
        assert self.script, f"unexpected {kind} at {address}"
        exp_kind, exp_addr, exp_payload, reply = self.script.pop(0)
        assert (kind, address, payload) == (exp_kind, exp_addr, exp_payload)
        return reply

    def write_registers(self, address, values, device_id=1):
        return self._next("write", address, list(values), device_id)

    def read_input_registers(self, address, count=1, device_id=1):
        return self._next("read_input", address, count, device_id)


@pytest.mark.parametrize("order", ["big", "little"])
def test_move_spin_stop_heartbeat_clear(order):
    a = [math.radians(10), math.radians(-20), math.radians(30)]
    c = ScriptedClient(
        [
            ("write", 0, f64(a, order), Reply()),  # POSITION_SETPOINT (HR 0..11)
            ("write", 25, [1], Reply()),  # COMMAND = MOVE
            ("write", 12 + 8, f64([math.radians(-15)], order), Reply()),  # RATE_SETPOINT of the inner axis
            ("write", 24, [2, 2], Reply()),  # COMMAND_AXIS = 2, COMMAND = SPIN
            ("write", 25, [3], Reply()),  # STOP
            ("write", 26, [1], Reply()),  # HEARTBEAT counter
            ("write", 27, [1], Reply()),  # FAULT_RESET
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
    c = ScriptedClient([("read_input", 0, 35, Reply(regs))])
    s = ModbusTurntable(c, word_order=order, limits=LIMITS).read_state()
    assert s.time == 12.5 and s.modes == (AxisMode.POSITION, AxisMode.POSITION, AxisMode.RATE)
    np.testing.assert_array_equal(s.angles, [0.1, 0.2, 0.3])
    assert s.rates[2] == -0.5 and s.status & TableStatus.AT_RATE


def test_fault_and_refusal_and_link_errors():
    regs = f64([1.0, 0, 0, 0, 0, 0, 0], "big") + [int(TableStatus.FAULT), int(FaultCode.STALL), 0, 0, 0, 0, 0]
    c = ScriptedClient(
        [
            ("read_input", 0, 35, Reply(regs)),
            ("write", 0, f64([0.0, 0.0, 0.0], "big"), Reply()),
            ("write", 25, [1], Reply(exception_code=4)),  # device failure: a fault is latched
            ("read_input", 28, 6, Reply([8, int(FaultCode.STALL), 0, 0, 0, int(FaultCode.STALL)])),
            ("read_input", 0, 35, None),
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

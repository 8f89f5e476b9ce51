"""Register maps as data: the shipped map, a PLC map with another layout (a file, no code), validation."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from pymodbus.client import ModbusTcpClient

from core.yaml_source import ConfigError
from drivers.modbus.register_map import DEFAULT_MAP, load_modbus_map
from drivers.modbus.table import ModbusTurntable
from drivers.protocols import AxisMode, FaultCode, TableError, TableStatus
from drivers.sim.modbus_controller import ModbusTableServer
from tests import REPO_ROOT
from tests.drivers.wire_support import make_world

PLC = REPO_ROOT / "tests" / "data" / "plc_table_map.yaml"


def test_shipped_map_is_the_documented_layout():
    m = load_modbus_map(DEFAULT_MAP)
    assert m.holding == {
        "position_setpoint": 0,
        "rate_setpoint": 12,
        "command_axis": 24,
        "command": 25,
        "heartbeat": 26,
        "fault_reset": 27,
    }
    assert m.state_span() == (0, 35) and m.state["limits"] == 40 and m.value_regs == 4


def test_plc_map_one_based_float32_degrees_holding_state():
    m = load_modbus_map(PLC)
    assert m.holding["command"] == 0 and m.state["status"] == 100  # 1-based numbers → 0-based wire addresses
    assert m.size("angles") == 6 and m.state_span() == (100, 26)
    assert m.status_from(0b1000001001) == TableStatus.REMOTE | TableStatus.IN_POSITION | TableStatus.INTERLOCK_OPEN
    assert m.unpack(m.pack([1.5, -2.25])) == [1.5, -2.25]


def test_a_plc_table_with_another_map_works_end_to_end():
    m = load_modbus_map(PLC)
    world = make_world(6)
    with ModbusTableServer(world, register_map=m) as srv:
        client = ModbusTcpClient("127.0.0.1", port=srv.port, timeout=0.5, retries=0)
        assert client.connect()
        try:
            t = ModbusTurntable(client, register_map=m)
            for got, want in zip(t.limits(), world.table_limits(), strict=True):
                assert got.rate_max == pytest.approx(want.rate_max, rel=1e-6)
            t.move_to([math.radians(20.0), math.radians(-30.0), math.radians(100.0)])
            for _ in range(20):
                world.produce(200)
                t.heartbeat()
            s = t.read_state()
            assert s.status & TableStatus.IN_POSITION and s.modes == (AxisMode.POSITION,) * 3
            np.testing.assert_allclose(np.degrees(s.angles), [20, -30, 100], atol=1e-3)  # float32 degrees
            assert s.time == pytest.approx(world.time, abs=1e-3)
            t.spin(1, math.radians(-12.0))
            for _ in range(10):
                world.produce(200)
                t.heartbeat()
            s = t.read_state()
            assert s.modes[1] == AxisMode.RATE and math.degrees(s.rates[1]) == pytest.approx(-12.0, abs=1e-3)
            t.stop()
            world.inject_fault(FaultCode.STALL)
            s = t.read_state()
            assert s.status & TableStatus.FAULT and s.fault_code == FaultCode.STALL
            with pytest.raises(TableError, match="STALL"):
                t.spin(0, 0.1)
            t.clear_fault()
            assert not t.read_state().status & TableStatus.FAULT
        finally:
            client.close()


@pytest.mark.parametrize(
    ("old", "new", "words"),
    [
        ("addressing: 1-based", "addressing: one", "0-based, 1-based"),
        ("  angles: 113", "  angles: 112", "overlaps state.time"),
        ("  command: 1\n", "  command: 0\n", "whole number in [1, 65535]"),
        ("INTERLOCK_OPEN: 9", "INTERLOCK_OPEN: 8", "also used by LIMIT"),
        ("INTERLOCK_OPEN: 9", "OPEN: 9", "unknown key"),
        ("modes: {STOP: 5, POSITION: 6, RATE: 7}", "modes: {STOP: 5, POSITION: 6}", "missing RATE"),
        ("value_type: float32", "value_type: float128", "float64, float32, int32"),
        ("  status: 101", "  status: 21", "overlaps holding.rate_setpoint"),
        ("  rates: 121", "  rates: 301", "one read allows 125"),
    ],
)
def test_map_mistakes_are_one_line_with_file_and_line(tmp_path: Path, old, new, words):
    text = PLC.read_text(encoding="utf-8")
    assert old in text
    f = tmp_path / "map.yaml"
    f.write_text(text.replace(old, new, 1), encoding="utf-8")
    with pytest.raises(ConfigError) as e:
        load_modbus_map(f)
    msg = str(e.value)
    assert words in msg and str(f) in msg and "\n" not in msg

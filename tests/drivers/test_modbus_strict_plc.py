"""A strict PLC table: another register map (per-axis control words, start coils, no AT_RATE bit, float32
degrees, little word order: drivers/modbus/maps/plc-per-axis.yaml), a watchdog that runs from power-up, a word
order that contradicts the map, implausible readings. Exact PDUs are written from the map file and the Modbus
specification (function codes 5, 16, 4), with the one transcript helper; never from the simulator."""

from __future__ import annotations

import io
import math
import struct
import time

import numpy as np
import pytest
from pymodbus.client import ModbusTcpClient

from benches.bench_config import load_bench
from benches.cli.commands import table as cmd
from benches.factory import Bench
from core.yaml_source import ConfigError
from drivers.modbus.register_map import WordOrderConflict, load_modbus_map
from drivers.modbus.table import ImplausibleReading, ModbusTurntable
from drivers.protocols import AxisLimits, AxisMode, LinkError, TableError, TableStatus
from drivers.sim.modbus_controller import ModbusTableServer
from tests import REPO_ROOT
from tests.drivers.transcript import ModbusTranscript, read_input, write_coil, write_registers
from tests.drivers.wire_support import make_world
from tests.simbench import bench_variant

PLC_MAP = REPO_ROOT / "drivers" / "modbus" / "maps" / "plc-per-axis.yaml"
LIMITS = (
    AxisLimits(rate_max=math.radians(300), accel_max=math.radians(100)),
    AxisLimits(rate_max=math.radians(200), accel_max=math.radians(100), position_min=-math.pi, position_max=math.pi),
    AxisLimits(rate_max=math.radians(200), accel_max=math.radians(100)),
)


def f32le(*values):
    """float32 values as registers, least significant word first (the map's word_order: little)."""
    out = []
    for v in values:
        hi, lo = struct.unpack(">2H", struct.pack(">f", v))
        out += [lo, hi]
    return out


def state_regs(t_ms, angles_deg, rates_deg, status=0, modes=(0, 0, 0)):
    """Input registers 1..21 of the example map (wire addresses 0..20)."""
    return f32le(t_ms, *angles_deg, *rates_deg) + [status, 0, *modes, 0, 0]


def plc(pairs):
    m = load_modbus_map(PLC_MAP)
    c = ModbusTranscript(pairs)
    return ModbusTurntable(c, register_map=m, limits=LIMITS, rate_tolerance=math.radians(0.01)), c


def test_per_axis_control_words_and_start_coils_exact_pdus():
    t, c = plc(
        [
            write_registers(0, f32le(10.0, -20.0, 30.0)),  # holding 1..6: position set-points (degrees)
            write_registers(30, [1, 1, 1]),  # holding 31..33: the three control words = move
            write_coil(0, True),  # coil 1: start move
            write_registers(10 + 4, f32le(-15.0)),  # holding 15..16: inner rate set-point (deg/s)
            write_registers(32, [2]),  # holding 33: inner control word = spin
            write_coil(1, True),  # coil 2: start spin
            write_registers(30, [3, 3, 3]),  # stop on every axis
            write_coil(2, True),  # coil 3: start stop
            write_registers(20, [1]),  # holding 21: heartbeat counter
            write_registers(21, [1]),  # holding 22: fault reset
        ]
    )
    t.move_to([math.radians(10), math.radians(-20), math.radians(30)])
    t.spin(2, math.radians(-15))
    t.stop()
    t.heartbeat()
    t.clear_fault()
    c.done()


def test_at_rate_judged_from_the_rates_when_the_map_has_no_bit():
    t, c = plc(
        [
            write_registers(10 + 2, f32le(12.0)),
            write_registers(31, [2]),
            write_coil(1, True),
            read_input(0, state_regs(1000.0, [0, 5, 0], [0, 11.9, 0], modes=(0, 2, 0))),
            read_input(0, state_regs(2000.0, [0, 17, 0], [0, 12.0, 0], modes=(0, 2, 0))),
        ]
    )
    t.spin(1, math.radians(12))
    s = t.read_state()
    assert not s.status & TableStatus.AT_RATE and s.modes[1] == AxisMode.RATE
    s = t.read_state()
    assert s.status & TableStatus.AT_RATE and s.time == pytest.approx(2.0)
    c.done()


def test_word_order_contradicting_the_map_is_refused_before_any_write():
    c = ModbusTranscript([])  # any request would fail the transcript
    with pytest.raises(WordOrderConflict, match=r"'big' contradicts the register map .*plc-per-axis.yaml.*little"):
        ModbusTurntable(c, word_order="big", register_map=load_modbus_map(PLC_MAP))
    c.done()


def test_word_order_contradiction_in_a_bench_file_names_both(tmp_path):
    bench = bench_variant(
        tmp_path,
        ctrl=("  controller: acutrol", "  controller: modbus-strict"),
        acl=(
            "  acl:                        # the simulated ACUTROL3000 (simulation.controller) answers like this\n"
            "    reply_profile: tcp\n    mode_reply: letter\n    decimals: 6\n"
            "    time_variable: 1          # its time clock: :Read:Variable? 1, in ms\n    time_scale_s: 0.001\n",
            f"  modbus_map: {PLC_MAP}\n  float_word_order: big\n",
        ),
    )
    with pytest.raises(ConfigError) as e:
        load_bench(bench)
    msg = str(e.value)
    assert "float_word_order" in msg and "'big'" in msg and "plc-per-axis.yaml" in msg and "word_order: little" in msg
    assert f"{bench}:" in msg and "\n" not in msg


@pytest.mark.parametrize(
    "regs,words",
    [
        (state_regs(1000.0, [0, 655360.0, 0], [0, 0, 0]), "middle angle 655360° outside its limits"),
        (state_regs(1000.0, [0, 0, 0], [1e5, 0, 0]), "outer rate 100000 °/s beyond its limit 300 °/s"),
        (state_regs(float("nan"), [0, 0, 0], [0, 0, 0]), "controller time nan s"),
        (state_regs(1000.0, [1e-40, 0, 0], [0, 0, 0]), "outer angle"),
    ],
)
def test_implausible_readings_are_refused_in_one_line(regs, words):
    t, c = plc([read_input(0, regs)])
    with pytest.raises(ImplausibleReading) as e:
        t.read_state()
    msg = str(e.value)
    assert words in msg and "check the word order" in msg and "\n" not in msg
    assert isinstance(e.value, LinkError)


def test_an_angle_jump_faster_than_the_rate_limit_is_refused():
    t, _ = plc(
        [
            read_input(0, state_regs(1000.0, [0, 0, 0], [0, 0, 0])),
            read_input(0, state_regs(1100.0, [90, 0, 0], [0, 0, 0])),
        ]
    )
    t.read_state()
    with pytest.raises(ImplausibleReading, match="outer angle jumped 90° in 0.1 s"):
        t.read_state()


def _strict_server(world, watchdog_s):
    return ModbusTableServer(
        world, register_map=load_modbus_map(PLC_MAP), watchdog_s=watchdog_s, watchdog_from_power_up=True
    )


def test_the_strict_plc_trips_on_a_move_without_heartbeat():
    world = make_world(3)
    with _strict_server(world, 0.3) as srv:
        client = ModbusTcpClient("127.0.0.1", port=srv.port, timeout=1.0, retries=0)
        assert client.connect()
        try:
            t = ModbusTurntable(client, register_map=load_modbus_map(PLC_MAP))
            time.sleep(0.45)  # the watchdog has run since power-up: no heartbeat yet
            with pytest.raises(TableError, match="COMMUNICATION_LOST"):
                t.move_to([0.1, 0.2, 0.3])
            assert srv.watchdog_tripped
        finally:
            client.close()


def test_table_command_status_move_spin_stop_on_a_strict_plc():
    """``tablebench table`` feeds the heartbeat: after pauses longer than the watchdog with nothing commanded
    (an operator reading the screen; the strict PLC's watchdog runs all the while), status and move work, then
    spin and stop, on the strict PLC with the other register map."""
    world = make_world(4)
    with _strict_server(world, 0.3) as srv:
        client = ModbusTcpClient("127.0.0.1", port=srv.port, timeout=1.0, retries=0)
        assert client.connect()
        try:
            t = ModbusTurntable(client, register_map=load_modbus_map(PLC_MAP))
            bench = Bench(t, None, world, "loopback", "strict PLC on loopback")  # type: ignore[arg-type]
            out = io.StringIO()
            for action, demand, pause in [
                ("status", (), 0.4),
                ("move", ([math.radians(20), math.radians(-30), math.radians(100)],), 0.4),
                ("spin", (1, math.radians(-12)), 0.0),
                ("stop", (), 0.0),
            ]:
                time.sleep(pause)
                assert cmd.execute(bench, action, demand, out=out) == 0, out.getvalue()
            text = out.getvalue()
            assert "settled:" in text and "outer 20.0000°" in text and "middle -30.0000°" in text
            assert "the middle axis is turning at -12 °/s" in text and "watchdog" in text
            assert "at rest:" in text and not srv.watchdog_tripped
            np.testing.assert_allclose(np.degrees(world.table_state().angles)[[0, 2]], [20, 100], atol=1e-3)
        finally:
            client.close()


def test_cli_table_on_a_simulated_strict_plc_with_the_per_axis_map(tmp_path):
    from tests.benches.test_table_command import cli

    bench = bench_variant(
        tmp_path,
        ctrl=("  controller: acutrol", "  controller: modbus-strict"),
        acl=(
            "  acl:                        # the simulated ACUTROL3000 (simulation.controller) answers like this\n"
            "    reply_profile: tcp\n    mode_reply: letter\n    decimals: 6\n"
            "    time_variable: 1          # its time clock: :Read:Variable? 1, in ms\n    time_scale_s: 0.001\n",
            f"  modbus_map: {PLC_MAP}\n",
        ),
    )
    r = cli("--transport", "loopback", "move", "10", "-20", "30", bench=bench)
    assert r.returncode == 0 and "settled" in r.stdout and "inner 30.0000°" in r.stdout, r.stderr
    r = cli("--transport", "loopback", "status", bench=bench)
    assert r.returncode == 0 and "strict" not in r.stderr, r.stderr

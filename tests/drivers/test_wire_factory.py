"""open_bench: in-process vs loopback (ACL via pyvisa-py, Modbus TCP) give identical samples; real-bench wiring."""

from __future__ import annotations

import dataclasses
import math
import socket
from pathlib import Path

import numpy as np
import pytest

from benches.bench_config import load_bench
from benches.factory import open_bench, open_table
from core.yaml_source import ConfigError
from drivers.protocols import AxisMode, LinkError, TableStatus
from tests import REPO_ROOT

BENCHES = REPO_ROOT / "benches"


@pytest.fixture(scope="module")
def sim_config():
    return load_bench(BENCHES / "sim.yaml")


def _script(bench) -> tuple[list, list]:
    """A short procedure-like command sequence: move, hold, spin, stop; heartbeat every block."""
    blocks, states = [], []

    def acquire(k):
        for _ in range(k):
            blocks.append(bench.unit.read(200))
            states.append(bench.turntable.read_state())
            bench.turntable.heartbeat()

    bench.turntable.move_to([math.radians(90.0), math.radians(-45.0), math.radians(30.0)])
    acquire(15)
    bench.turntable.spin(0, math.radians(25.0))
    acquire(10)
    bench.turntable.stop()
    acquire(5)
    return blocks, states


def _cat(blocks, name):
    return np.concatenate([getattr(b, name) for b in blocks])


def _variant(cfg, controller):
    if controller == "acutrol":
        return cfg
    if controller == "acutrol-gpib":  # GPIB reply profile (commands unanswered) over the socket, word mode replies
        acl = dataclasses.replace(cfg.turntable.acl, reply_profile="gpib", mode_reply="word", axes=(3, 1, 2))
        return dataclasses.replace(cfg, turntable=dataclasses.replace(cfg.turntable, acl=acl))
    tt = dataclasses.replace(cfg.turntable, sim_controller="modbus", acl=None, watchdog=2.0)
    return dataclasses.replace(cfg, turntable=tt)


@pytest.mark.parametrize("controller", ["acutrol", "acutrol-gpib", "modbus"])
def test_loopback_is_bit_identical_to_in_process(sim_config, controller):
    cfg = _variant(sim_config, controller)
    with open_bench(cfg, seed=42, transport="in-process") as a:
        assert a.transport == "in-process" and a.world is not None
        ba, sa = _script(a)
    with open_bench(cfg, seed=42, transport="loopback") as b:
        assert b.transport == "loopback" and b.world is not None
        assert ("ACUTROL (ACL via pyvisa-py TCPIP0::127.0.0.1::" if controller != "modbus" else "Modbus TCP") in (
            b.describe()
        )
        bb, sb = _script(b)
    for name in ("counter", "time", "temperature", "status", "accel", "gyro"):
        assert np.array_equal(_cat(ba, name), _cat(bb, name)), name
    assert sum(x.dropped + x.rejected for x in bb) == 0
    for x, y in zip(sa, sb, strict=True):
        assert x.time == y.time and x.status == y.status and x.modes == y.modes and x.fault_code == y.fault_code
        assert np.array_equal(x.angles, y.angles) and np.array_equal(x.rates, y.rates)
    assert sa[14].status & TableStatus.IN_POSITION


def test_close_is_idempotent_and_stops_servers(sim_config):
    bench = open_bench(sim_config, seed=1, transport="loopback")
    port = bench.unit.port
    bench.close()
    bench.close()
    assert not port.is_open
    with pytest.raises(LinkError):
        bench.unit.read(1)


def test_bad_transport_choices(sim_config):
    with pytest.raises(ConfigError, match="transport 'wifi'"):
        open_bench(sim_config, transport="wifi")
    with pytest.raises(ConfigError, match="simulated bench"):
        open_bench(sim_config, transport="hardware")
    for name in ("example-real.yaml", "example-modbus.yaml"):
        real = load_bench(BENCHES / name)
        with pytest.raises(ConfigError, match="real bench"):
            open_bench(real, transport="loopback")


def test_hardware_path_against_the_simulators(sim_config):
    """The real-bench wiring (addresses → clients → drivers), served by the simulators on 127.0.0.1."""
    from drivers.sim.modbus_controller import ModbusTableServer
    from drivers.sim.serial_unit import SerialUnitServer
    from drivers.sim.world import SimulatedWorld

    real = load_bench(BENCHES / "example-modbus.yaml")
    world = SimulatedWorld.from_bench(sim_config, 3)
    with (
        ModbusTableServer(world, word_order=real.turntable.float_word_order) as mb,
        SerialUnitServer(world, stream_factor=50.0) as su,
    ):
        cfg = dataclasses.replace(
            real,
            turntable=dataclasses.replace(real.turntable, address=f"127.0.0.1:{mb.port}"),
            unit=dataclasses.replace(real.unit, address=su.url, scale=world.scale, sample_rate=world.sample_rate),
        )
        with open_bench(cfg) as bench:
            assert bench.transport == "hardware" and bench.world is None
            block = bench.unit.read(100)
            assert len(block) == 100 and block.dropped == 0
            state = bench.turntable.read_state()
            assert state.time > 0


def test_acutrol_bench_opens_its_visa_resource(sim_config):
    """example-real.yaml (ACUTROL, VISA TCPIP SOCKET) against the simulated ACUTROL: idn, move, the table
    commanded Off when the bench closes, interlocks opened as the bench asks."""
    from drivers.sim.acl_server import AclTableServer
    from drivers.sim.world import SimulatedWorld

    real = load_bench(BENCHES / "example-real.yaml")
    world = SimulatedWorld.from_bench(sim_config, 3)
    with AclTableServer(world, real.turntable.acl) as srv:
        cfg = dataclasses.replace(real, turntable=dataclasses.replace(real.turntable, resource=srv.resource))
        with open_table(cfg) as bench:
            assert "ACUTROL (ACL) at TCPIP0::127.0.0.1::" in bench.describe() and bench.unit is None
            bench.turntable.spin(2, math.radians(10.0))
            world.produce(2000)
            assert bench.turntable.read_state().modes[2] == AxisMode.RATE
        assert srv.controller.mode == ["OFF", "OFF", "OFF"] and srv.controller.servoed == [False, False, False]


def test_hardware_unreachable_is_a_link_error(sim_config):
    real = load_bench(BENCHES / "example-modbus.yaml")
    s = socket.socket()
    s.bind(("127.0.0.1", 0))
    free = s.getsockname()[1]
    s.close()
    cfg = dataclasses.replace(real, turntable=dataclasses.replace(real.turntable, address=f"127.0.0.1:{free}"))
    with pytest.raises(LinkError, match="no Modbus TCP answer"):
        open_bench(cfg)
    cfg = dataclasses.replace(real, turntable=dataclasses.replace(real.turntable, address="127.0.0.1:notaport"))
    with pytest.raises(ConfigError, match="port must be an integer"):
        open_bench(cfg)
    acl = load_bench(BENCHES / "example-real.yaml")
    cfg = dataclasses.replace(
        acl, turntable=dataclasses.replace(acl.turntable, resource=f"TCPIP0::127.0.0.1::{free}::SOCKET")
    )
    with pytest.raises(LinkError, match="no answer from the ACUTROL at TCPIP0::127.0.0.1::.*check power"):
        open_table(cfg)
    cfg = dataclasses.replace(acl, turntable=dataclasses.replace(acl.turntable, resource="GPIB0::1::INSTR"))
    with pytest.raises(LinkError, match="linux-gpib or gpib-ctypes"):
        open_table(cfg)


def _run_session(tmp_path: Path, transport: str, procedure: str, overrides: dict | None) -> dict:
    import io

    from benches import session
    from benches.recording import open_recording

    prep = session.prepare(BENCHES / "sim.yaml", procedure, overrides)
    folder = tmp_path / transport
    folder.mkdir()
    session.execute(prep, folder, seed=11, transport=transport, stream=io.StringIO(), live=False)
    with open_recording(folder) as rec:
        assert rec.header.transport == transport
        smp, table = rec.samples(), rec.table()
        return {
            "accel": smp.accel,
            "gyro": smp.gyro,
            "counter": smp.counter,
            "table_time": table.time,
            "table_angles": table.angles,
            "table_status": table.status,
        }


@pytest.mark.parametrize(
    "procedure,overrides",
    [
        ("static-noise", {"duration_s": 20.0, "warmup_s": 5.0}),
        pytest.param("ten-step", None, marks=pytest.mark.slow),
    ],
)
def test_session_recordings_identical_over_loopback(tmp_path, procedure, overrides):
    """The shipped simulated bench (a simulated ACUTROL): the run over ACL, TCP and pyvisa-py records exactly
    what the in-process run records (the wire carries the controller's decimals both ways)."""
    a = _run_session(tmp_path, "in-process", procedure, overrides)
    b = _run_session(tmp_path, "loopback", procedure, overrides)
    for k in a:
        assert np.array_equal(a[k], b[k]), k

"""open_bench: in-process vs loopback (Modbus and ASCII) give identical samples; real-bench wiring."""

from __future__ import annotations

import dataclasses
import math
import socket
from pathlib import Path

import numpy as np
import pytest

from benches.bench_config import load_bench
from benches.factory import open_bench
from core.yaml_source import ConfigError
from drivers.protocols import LinkError, TableStatus
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


@pytest.mark.parametrize("driver", ["sim", "ascii-serial"])
def test_loopback_is_bit_identical_to_in_process(sim_config, driver):
    cfg = dataclasses.replace(sim_config, turntable=dataclasses.replace(sim_config.turntable, driver=driver))
    with open_bench(cfg, seed=42, transport="in-process") as a:
        assert a.transport == "in-process" and a.world is not None
        ba, sa = _script(a)
    with open_bench(cfg, seed=42, transport="loopback") as b:
        assert b.transport == "loopback" and b.world is not None
        assert ("ASCII" if driver == "ascii-serial" else "Modbus TCP") in b.describe()
        bb, sb = _script(b)
    for name in ("counter", "time", "temperature", "status"):
        assert np.array_equal(_cat(ba, name), _cat(bb, name)), name
    for name, lsb in (("accel", cfg.unit.scale.accel_lsb), ("gyro", cfg.unit.scale.gyro_lsb)):
        if driver == "sim":  # Modbus float64: bit for bit
            assert np.array_equal(_cat(ba, name), _cat(bb, name)), name
        else:  # ASCII degrees text: commands exact to ~1 ulp of the angle → at most an occasional count
            assert np.max(np.abs(_cat(ba, name) - _cat(bb, name))) <= 1.5 * lsb, name
    assert sum(x.dropped + x.rejected for x in bb) == 0
    for x, y in zip(sa, sb, strict=True):
        assert x.time == y.time and x.status == y.status and x.modes == y.modes and x.fault_code == y.fault_code
        if driver == "sim":
            assert np.array_equal(x.angles, y.angles) and np.array_equal(x.rates, y.rates)
        else:
            np.testing.assert_allclose(y.angles, x.angles, rtol=1e-14, atol=1e-15)
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
    real = load_bench(BENCHES / "example-real.yaml")
    with pytest.raises(ConfigError, match="real bench"):
        open_bench(real, transport="loopback")


def test_hardware_path_against_the_simulators(sim_config):
    """The real-bench wiring (addresses → clients → drivers), served by the simulators on 127.0.0.1."""
    from drivers.sim.modbus_controller import ModbusTableServer
    from drivers.sim.serial_unit import SerialUnitServer
    from drivers.sim.world import SimulatedWorld

    real = load_bench(BENCHES / "example-real.yaml")
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


def test_hardware_unreachable_is_a_link_error(sim_config):
    real = load_bench(BENCHES / "example-real.yaml")
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
    a = _run_session(tmp_path, "in-process", procedure, overrides)
    b = _run_session(tmp_path, "loopback", procedure, overrides)
    for k in a:
        assert np.array_equal(a[k], b[k]), k

"""The simulated Ideal Aerosmith controller served on loopback TCP in its text language, reached by the real
driver through pyserial's ``socket://`` URL (as a serial device server): the bytes on the wire are the public
command set's (docs/protocols/ideal-aerosmith.md: the ``aerosmith`` package sends the three letters and the
number with nothing appended; a reply is the controller's text, then the prompt CR LF > CR LF), and a run over
loopback equals the in-process run on the example bench."""

from __future__ import annotations

import math
import re
import socket

import numpy as np
import pytest

from benches import factory
from benches.bench_config import load_bench
from benches.recording import open_recording
from drivers import connect
from drivers.aerosmith import AerosmithSettings, AerosmithTable
from drivers.protocols import TableError
from drivers.sim.aerosmith_server import AerosmithTableServer
from drivers.sim.loopback import Loopback
from drivers.sim.table_twins import AerosmithTwin
from drivers.sim.world import SimulatedWorld
from tests import REPO_ROOT
from tests.simbench import run_procedure

BENCH = REPO_ROOT / "benches" / "sim-ideal-aerosmith.yaml"
PROMPT = b"\r\n>\r\n"


class Tap:
    """A byte stream that keeps what the driver writes (the bytes that go on the wire)."""

    def __init__(self, stream) -> None:
        self.s = stream
        self.sent: list[bytes] = []

    def write(self, data: bytes) -> int:
        self.sent.append(bytes(data))
        return self.s.write(data)

    def __getattr__(self, name):
        return getattr(self.s, name)


def _world() -> SimulatedWorld:
    return SimulatedWorld.from_bench(load_bench(BENCH), 3)


@pytest.mark.parametrize("terminator", ["", "\r"])
def test_the_driver_over_loopback_sends_the_public_command_bytes(terminator):
    settings = AerosmithSettings(command_terminator=terminator)
    world = _world()
    srv = AerosmithTableServer(world, settings)
    taps: list[Tap] = []

    def wrap(port):
        taps.append(Tap(port))
        return taps[0]

    conn = connect.aerosmith_table(
        srv.url, lambda s: AerosmithTable(s, world.table_limits(), settings=settings), timeout=2.0, wrap=wrap
    )
    try:
        t = conn.driver
        t.spin(2, math.radians(-12.5))
        world.produce(int(world.sample_rate))  # one second of bench time: the table reaches its rate
        s = t.read_state()
        t.stop()
        T = terminator.encode()
        assert taps[0].sent == [b"SRV1" + T, b"ACL80" + T, b"JOG-12.5" + T, b"POS?" + T, b"RAT?" + T, b"STO" + T]
        assert s.rates[2] == pytest.approx(math.radians(-12.5), abs=math.radians(1e-3))  # the table's rate error
        with pytest.raises(TableError, match="refused 'JOG-400'"):  # the controller's own refusal, over the wire
            t.command("JOG-400")
    finally:
        conn.close()
        srv.close()


def test_the_servers_reply_bytes():
    """What the host reads back, byte for byte: a number then the prompt; an error text then the prompt; the
    prompt alone for an accepted command."""
    srv = AerosmithTableServer(_world(), AerosmithSettings(command_terminator="\r"))
    try:
        with socket.create_connection(("127.0.0.1", srv.port), timeout=2.0) as c:

            def ask(cmd: bytes) -> bytes:
                c.sendall(cmd)
                got = b""
                while not got.endswith(PROMPT):
                    got += c.recv(4096)
                return got

            assert ask(b"SRV1\r") == PROMPT
            pos = ask(b"POS?\r")  # degrees with 6 decimals (the simulated table's angle error: near, not at, 0)
            assert re.fullmatch(rb"-?\d+\.\d{6}\r\n" + re.escape(PROMPT), pos) and abs(float(pos[:-7])) < 1e-3
            bad = ask(b"JOG999\r")
            assert bad.startswith(b"ERROR ") and bad.endswith(PROMPT) and bad.count(PROMPT) == 1
    finally:
        srv.close()


def test_loopback_object_and_factory_serve_the_aerosmith_dialect():
    world = _world()
    with Loopback(world, table=AerosmithTwin(AerosmithSettings())) as lb:
        assert "Ideal Aerosmith" in lb.describe() and "socket://127.0.0.1:" in lb.describe()
        lb.turntable.spin(2, math.radians(5))
        lb.unit.read(100)
        assert lb.turntable.read_state().rates[2] > 0
        lb.turntable.stop()
    bench = factory.open_table(load_bench(BENCH), seed=1, transport="loopback")
    try:
        assert "over pyserial socket://127.0.0.1:" in bench.description
    finally:
        bench.close()


SPIN_Y = """name: inner-spin
description: warm-up, hold, a spin about the inner gimbal's axis both ways, home, hold (a single-axis table)
version: 1
defaults: {settle_s: 1, hold_s: 3, spin_settle_s: 1}
steps:
  - warmup: {duration_s: 3, at: {z: Up, x: East}}
  - hold: {}
  - spin: {axis: y, rate_dps: 20, direction: both, revolutions: 1}
  - orient: {z: Up, x: East}
  - hold: {}
"""


def test_a_run_over_loopback_equals_the_in_process_run(tmp_path):
    """Same seed, same commands: the table's readings are the same to the last bit (both drivers read the same
    controller on the same world clock) and the samples equal up to the KVH frame's float32 quantisation."""
    proc = tmp_path / "inner-spin.yaml"
    proc.write_text(SPIN_Y, encoding="utf-8")
    wire = run_procedure(tmp_path, BENCH, str(proc), seed=4, out="loopback", transport="loopback")
    local = run_procedure(tmp_path, BENCH, str(proc), seed=4, out="in-process", transport="in-process")
    with open_recording(wire) as a, open_recording(local) as b:
        ta, tb = a.table(), b.table()
        sa, sb = a.samples(fields=("gyro", "accel")), b.samples(fields=("gyro", "accel"))
        events = [e.message for e in a.events()]
    assert any("Ideal Aerosmith" in e and "socket://" in e for e in events)
    assert len(ta) == len(tb) and len(sa.gyro) == len(sb.gyro) > 0
    np.testing.assert_array_equal(ta.angles, tb.angles)
    np.testing.assert_array_equal(ta.rates, tb.rates)
    assert np.max(np.abs(ta.rates[:, 2])) == pytest.approx(math.radians(20), abs=math.radians(2e-3))  # rate error
    assert np.all(ta.angles[:, :2] == 0)  # the absent gimbals never moved
    np.testing.assert_allclose(sa.gyro, sb.gyro, rtol=0, atol=1e-6)
    np.testing.assert_allclose(sa.accel, sb.accel, rtol=0, atol=1e-5)


def test_the_real_example_bench_loads_and_check_refuses_what_it_cannot_do():
    """benches/example-ideal-aerosmith.yaml (a real single-axis table with an Epson M-G370): loads, names its
    frame, and ``check`` refuses the ten-step sequence (outer/middle gimbals absent) in one line, exit 2,
    while a static procedure passes — without any hardware attached."""
    import subprocess
    import sys

    from benches.session import prepare

    real = REPO_ROOT / "benches" / "example-ideal-aerosmith.yaml"
    b = load_bench(real)
    assert b.simulation is None and b.turntable.driver == "ideal-aerosmith" and b.unit.frame == "epson-g370-burst"
    prepare(real, "static-noise", {"duration_s": 60.0})
    r = subprocess.run(
        [sys.executable, "-m", "benches.cli", "check", "ten-step", "--bench", str(real)],
        cwd=REPO_ROOT,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert r.returncode == 2 and "has no such axis" in r.stderr and len(r.stderr.strip().splitlines()) == 1

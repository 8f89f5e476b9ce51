"""SerialInertialUnit against the simulated serial unit on loopback TCP (pyserial socket:// URLs)."""

from __future__ import annotations

import socket
import threading
import time

import numpy as np
import pytest
import serial

from drivers import connect
from drivers.imu_unit.counts import frames_to_block
from drivers.imu_unit.serial_unit import SerialInertialUnit
from drivers.protocols import InertialUnit, LinkError
from drivers.sim.serial_unit import Corruption, SerialUnitServer
from tests.drivers.wire_support import make_world


@pytest.fixture
def served():
    """(world, server, port, unit) in polled mode; everything closed afterwards."""
    opened = []

    def make(seed=1, corruption=None, polled=True, stream_factor=0.0, timeout=1.0):
        world = make_world(seed)
        srv = SerialUnitServer(world, corruption=corruption, stream_factor=stream_factor)
        opened.append(srv.close)
        conn = connect.serial_unit(srv.url, world.scale, world.sample_rate, timeout=timeout, polled=polled)
        opened.append(conn.close)
        return world, srv, conn.transport, conn.driver

    yield make
    for fn in reversed(opened):
        fn()


def test_polled_reads_match_the_world_bit_for_bit(served):
    world, srv, _port, unit = served(seed=3)
    assert isinstance(unit, InertialUnit)
    blocks = [unit.read(n) for n in (1, 199, 500, 300)]
    assert world.samples_produced == 1000  # the clock advanced exactly with what was read
    ref = make_world(3)
    expect = [frames_to_block(ref.produce(n), ref.scale) for n in (1, 199, 500, 300)]
    for b, e in zip(blocks, expect, strict=True):
        assert np.array_equal(b.accel, e.accel) and np.array_equal(b.gyro, e.gyro)
        assert np.array_equal(b.time, e.time) and np.array_equal(b.counter, e.counter)
        assert np.array_equal(b.temperature, e.temperature)
        assert b.dropped == 0 and b.rejected == 0


def test_corrupted_stream_resyncs_counts_and_stays_correct(served):
    corr = Corruption(garbage=0.02, flip=0.02, drop=0.01, seed=11)
    world, srv, _port, unit = served(seed=4, corruption=corr)
    blocks = [unit.read(250) for _ in range(8)]
    ref = make_world(4)
    truth = frames_to_block(ref.produce(2000), ref.scale)
    counters = np.concatenate([b.counter for b in blocks]).astype(np.int64)
    accel = np.concatenate([b.accel for b in blocks])
    assert np.all(np.diff(counters) > 0)
    pos = np.searchsorted(truth.counter.astype(np.int64), counters)
    assert np.array_equal(truth.counter[pos].astype(np.int64), counters)
    assert np.array_equal(truth.accel[pos], accel)  # every accepted sample is the true one
    inj = srv.injected
    assert inj["flip"] > 0 and inj["drop"] > 0 and inj["garbage"] > 0
    rejected = sum(b.rejected for b in blocks)
    dropped = sum(b.dropped for b in blocks)
    missing = np.setdiff1d(np.arange(int(counters[-1]) + 1), counters)
    lost = np.asarray(srv.lost_counters)
    assert np.array_equal(missing, lost[lost <= counters[-1]])  # exactly the destroyed frames are missing
    assert dropped == missing.size - int(counters[0])  # the gap before the very first frame is unknowable
    assert 0 < rejected <= inj["flip"] + inj["garbage"]  # CRC failures: flipped frames, fake headers in garbage
    assert unit.rejected_total == rejected and unit.dropped_total == dropped


def test_lost_tail_of_a_burst_returns_quickly_with_the_loss_counted(served):
    corr = Corruption(drop=0.5, seed=2)
    _world, _srv, _port, unit = served(seed=5, corruption=corr, timeout=5.0)
    t0 = time.monotonic()
    blocks = [unit.read(20) for _ in range(5)]
    assert time.monotonic() - t0 < 4.0  # the idle-gap rule ends short bursts, not the 5 s timeout
    assert any(len(b) < 20 for b in blocks)
    counters = np.concatenate([b.counter for b in blocks]).astype(np.int64)
    assert np.all(np.diff(counters) > 0) and counters[-1] < 100  # never more than the 5 × 20 requested
    # every frame is accounted for, received or counted as dropped (except before the very first one)
    assert len(counters) + sum(b.dropped for b in blocks) == counters[-1] - counters[0] + 1


def test_free_running_stream(served):
    _world, _srv, _port, unit = served(seed=6, polled=False, stream_factor=20.0)
    b1 = unit.read(300)
    b2 = unit.read(300)
    assert len(b1) == 300 and len(b2) == 300
    assert int(b2.counter[0]) == int(b1.counter[-1]) + 1  # surplus frames are kept, nothing lost
    assert b2.dropped == 0


def test_dropped_connection_raises_link_error_quickly(served):
    _world, srv, _port, unit = served(seed=7, timeout=5.0)
    unit.read(10)
    srv.disconnect()
    t0 = time.monotonic()
    with pytest.raises(LinkError, match="serial link failed|no data"):
        unit.read(10)
    assert time.monotonic() - t0 < 1.0


def test_silent_device_times_out_with_a_clear_message():
    lst = socket.create_server(("127.0.0.1", 0))
    conns = []
    t = threading.Thread(target=lambda: conns.append(lst.accept()), daemon=True)
    t.start()
    port = serial.serial_for_url(f"socket://127.0.0.1:{lst.getsockname()[1]}", timeout=0.02)
    try:
        from drivers.imu_unit.counts import CountScale

        unit = SerialInertialUnit(port, CountScale(1e-6, 1e-7), 1000.0, timeout=0.3, polled=True)
        t0 = time.monotonic()
        with pytest.raises(LinkError, match=r"no data for 0.3 s \(0 of 5 frames"):
            unit.read(5)
        assert time.monotonic() - t0 < 1.5
    finally:
        port.close()
        for c, _ in conns:
            c.close()
        lst.close()


def test_bad_arguments():
    from drivers.imu_unit.counts import CountScale

    with pytest.raises(ValueError, match="sample_rate"):
        SerialInertialUnit(object(), CountScale(1, 1), 0.0)

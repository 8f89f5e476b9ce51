"""Simulated turntable: profiles within limits, IN_POSITION / AT_RATE, refusals, faults, watchdog."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from analysis.units import ARCSEC, DEG
from drivers.protocols import AxisLimits, AxisMode, FaultCode, InertialUnit, TableError, TableStatus, Turntable
from drivers.sim.config import ScheduledFault, SimConfig, TableModel
from drivers.sim.inprocess import SimInertialUnit, SimTurntable
from drivers.sim.world import SimulatedWorld

FS = 1000.0


def _bench(**table_kw) -> tuple[SimulatedWorld, SimTurntable, SimInertialUnit]:
    cfg = SimConfig(table=replace(TableModel(), **table_kw))
    w = SimulatedWorld(cfg, seed=11)
    return w, SimTurntable(w), SimInertialUnit(w)


def _trace(w: SimulatedWorld, t: SimTurntable, seconds: float, step: int = 5, heartbeat: bool = True):
    """Read the table every ``step`` samples for ``seconds``; returns (times, angles, rates, statuses)."""
    ts, angs, rates, sts = [], [], [], []
    for _ in range(int(seconds * FS / step)):
        w.produce(step)
        if heartbeat:
            t.heartbeat()
        s = t.read_state()
        ts.append(s.time)
        angs.append(s.angles)
        rates.append(s.rates)
        sts.append(s.status)
    return np.array(ts), np.array(angs), np.array(rates), sts


def test_protocols_are_implemented() -> None:
    w, t, u = _bench()
    assert isinstance(t, Turntable) and isinstance(u, InertialUnit)


def test_move_respects_limits_and_reaches_in_position() -> None:
    w, t, _ = _bench()
    lim = t.limits()
    target = np.array([2.5, -1.2, 7.0])  # > 2π on the inner axis: absolute, unwrapped
    t.move_to(target)
    assert t.read_state().status & TableStatus.MOVING
    ts, ang, rate, sts = _trace(w, t, 8.0, step=2)
    rmax = np.array([a.rate_max for a in lim])
    amax = np.array([a.accel_max for a in lim])
    assert np.all(np.abs(rate) <= rmax * 1.001)
    # peak rate: the slew rate, or the triangular-profile peak √(d·a) for a short move
    peak = np.minimum(0.9 * rmax, np.sqrt(np.abs(target) * amax))
    np.testing.assert_allclose(np.max(np.abs(rate), axis=0), peak, rtol=0.01)
    acc = np.diff(rate, axis=0) / np.diff(ts)[:, None]
    assert np.all(np.abs(acc) <= amax * 1.02)
    inpos = [bool(s & TableStatus.IN_POSITION) for s in sts]
    assert inpos[-1] and not inpos[0]
    first = inpos.index(True)
    assert all(inpos[first:])  # stays in position
    tol = w.cfg.table.position_tolerance
    assert np.all(np.abs(ang[first:] - target) < tol)
    # overshoot happened (settling transient) but is small
    over = (ang[:, 2] - target[2]).max()
    assert 0 < over < 10 * ARCSEC
    assert not sts[-1] & TableStatus.MOVING
    assert t.read_state().modes == (AxisMode.POSITION,) * 3


def test_rate_command_ramps_and_reports_at_rate_and_unwrapped_angles() -> None:
    w, t, _ = _bench()
    rate = 200 * DEG
    t.spin(0, rate)
    ramp = rate / t.limits()[0].accel_max
    ts, ang, rates, sts = _trace(w, t, 5.0)
    at = [bool(s & TableStatus.AT_RATE) for s in sts]
    first = at.index(True)
    assert ts[first] == pytest.approx(ramp, abs=0.01)
    assert np.allclose(rates[first:, 0], rate, atol=1e-3 * DEG)
    assert ang[-1, 0] > 2 * math.pi  # 5 s at up to 200 °/s: > 2 turns, reported unwrapped
    t.stop()
    ts, ang, rates, sts = _trace(w, t, 3.0)
    assert not sts[-1] & TableStatus.MOVING and abs(rates[-1, 0]) < 1e-9


def test_out_of_limit_commands_raise_and_do_not_move() -> None:
    lim = AxisLimits(rate_max=100 * DEG, accel_max=50 * DEG, position_min=-90 * DEG, position_max=90 * DEG)
    w, t, _ = _bench(limits=(lim, lim, lim))
    before = t.read_state().angles
    with pytest.raises(TableError, match="outside its limits"):
        t.move_to([0.0, 100 * DEG, 0.0])
    with pytest.raises(TableError, match="exceeds its limit"):
        t.spin(1, 101 * DEG)
    with pytest.raises(TableError):
        t.move_to([0.0, float("nan"), 0.0])
    ts, ang, rates, sts = _trace(w, t, 0.5)
    assert np.allclose(ang, before, atol=1 * ARCSEC) and not any(s & TableStatus.MOVING for s in sts)
    assert t.read_state().fault_code == FaultCode.NONE


def test_spinning_into_a_position_limit_latches_limit_fault() -> None:
    lim = AxisLimits(rate_max=100 * DEG, accel_max=50 * DEG, position_min=-30 * DEG, position_max=30 * DEG)
    w, t, _ = _bench(limits=(lim, lim, lim))
    t.spin(2, 40 * DEG)
    ts, ang, rates, sts = _trace(w, t, 2.0)
    s = t.read_state()
    assert s.fault_code == FaultCode.POSITION_LIMIT and s.status & TableStatus.LIMIT
    assert ang[:, 2].max() <= 30 * DEG + 1 * ARCSEC and abs(s.rates[2]) == 0.0


def test_stall_latches_and_inhibits_until_cleared() -> None:
    w, t, _ = _bench()
    t.move_to([3.0, 0.0, 0.0])
    _trace(w, t, 0.5)
    w.inject_fault(FaultCode.STALL)
    s = t.read_state()
    assert s.status & TableStatus.FAULT and s.fault_code == FaultCode.STALL
    frozen = s.angles.copy()
    ts, ang, rates, sts = _trace(w, t, 1.0)
    assert np.allclose(ang, frozen, atol=1 * ARCSEC) and np.all(rates == 0.0)
    with pytest.raises(TableError, match="STALL"):
        t.move_to([0.0, 0.0, 0.0])
    with pytest.raises(TableError):
        t.spin(0, 1.0)
    t.stop()  # always accepted
    t.clear_fault()
    assert not t.read_state().status & TableStatus.FAULT
    t.move_to([0.0, 0.0, 0.0])
    _, ang, _, sts = _trace(w, t, 4.0)
    assert sts[-1] & TableStatus.IN_POSITION and np.allclose(ang[-1], 0.0, atol=2 * ARCSEC)


def test_scheduled_fault_from_config() -> None:
    cfg = SimConfig(faults=(ScheduledFault(time=1.2345, fault=FaultCode.AMPLIFIER),))
    w = SimulatedWorld(cfg, seed=0)
    t = SimTurntable(w)
    t.spin(0, 10 * DEG)
    ts, ang, rates, sts = _trace(w, t, 2.0, step=1)
    k = [bool(s & TableStatus.FAULT) for s in sts].index(True)
    assert ts[k] == pytest.approx(1.235, abs=1.5e-3)
    assert t.read_state().fault_code == FaultCode.AMPLIFIER


@pytest.mark.parametrize("heartbeat", [True, False])
def test_watchdog_brings_table_to_rest_without_heartbeat(heartbeat: bool) -> None:
    w, t, _ = _bench(watchdog=1.0)
    t.spin(1, 50 * DEG)
    ts, ang, rates, sts = _trace(w, t, 4.0, heartbeat=heartbeat)
    s = t.read_state()
    if heartbeat:
        assert s.fault_code == FaultCode.NONE and rates[-1, 1] == pytest.approx(50 * DEG, rel=1e-3)
    else:
        assert s.status & TableStatus.WATCHDOG and s.fault_code == FaultCode.COMMUNICATION_LOST
        assert not s.status & TableStatus.MOVING and np.all(np.abs(rates[-1]) < 1e-12)
        # the stop started at 1 s of bench time and was a controlled deceleration
        moving = np.abs(rates[:, 1]) > 0
        t_rest = ts[np.flatnonzero(moving)[-1]]
        assert t_rest == pytest.approx(1.0 + 50 / 100, abs=0.02)  # 50 °/s at 100 °/s²


def test_unit_reads_advance_the_shared_clock_and_count_drops() -> None:
    cfg = SimConfig(drop_probability=0.05)
    w = SimulatedWorld(cfg, seed=4)
    u = SimInertialUnit(w)
    b1, b2 = u.read(1000), u.read(1000)
    assert w.time == pytest.approx(2.0)
    # every sample period is either delivered or counted as dropped (trailing drops count in the next block)
    last = int(b2.counter[-1])
    assert len(b1) + len(b2) + b1.dropped + b2.dropped == last + 1
    assert len(b1) + b1.dropped == int(b1.counter[-1]) + 1
    assert 40 < b1.dropped + b2.dropped < 170  # 5 % of 2000 = 100 expected


def test_interlock_stops_under_control_and_latches() -> None:
    w, t, _ = _bench()
    t.spin(0, 80 * DEG)
    _trace(w, t, 1.5)
    w.inject_fault(FaultCode.INTERLOCK)
    s = t.read_state()
    assert s.status & TableStatus.INTERLOCK_OPEN and s.status & TableStatus.MOVING  # decelerating, not cut
    ts, ang, rates, sts = _trace(w, t, 1.5)
    assert np.all(np.abs(np.diff(rates[:, 0])) / np.diff(ts) <= t.limits()[0].accel_max * 1.01)
    assert not sts[-1] & TableStatus.MOVING and rates[-1, 0] == 0.0
    with pytest.raises(TableError):
        t.spin(0, 1.0)


def test_concurrent_access_from_threads() -> None:
    import threading

    w, t, _ = _bench()
    errors: list[BaseException] = []

    def producer() -> None:
        try:
            for _ in range(50):
                w.produce(100)
        except BaseException as exc:  # pragma: no cover - reported below
            errors.append(exc)

    def poller() -> None:
        try:
            for i in range(300):
                s = w.table_state()
                w.heartbeat()
                assert 0.0 <= s.time <= 5.0
                if i == 10:
                    w.command_rate(2, 30 * DEG)
        except BaseException as exc:  # pragma: no cover - reported below
            errors.append(exc)

    threads = [threading.Thread(target=producer), threading.Thread(target=poller)]
    for th in threads:
        th.start()
    for th in threads:
        th.join(timeout=60)
    assert not errors and w.samples_produced == 5000


def test_timestamps_counter_and_jitter() -> None:
    f = SimulatedWorld(SimConfig(), 0).produce(1000)
    np.testing.assert_array_equal(f.timestamp_ns, f.counter.astype(np.uint64) * np.uint64(1_000_000))
    fj = SimulatedWorld(SimConfig(timestamp_jitter=2e-6), 0).produce(20_000)
    err = fj.timestamp_ns.astype(np.float64) - fj.counter.astype(np.float64) * 1e6
    assert np.std(err[1:]) == pytest.approx(2000.0, rel=0.03)
    assert np.all(np.diff(fj.timestamp_ns.astype(np.int64)) > 0)

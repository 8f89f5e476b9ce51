"""The time-base estimate against an independent, analytic two-clock bench (not the project's simulator).

One gimbal (the inner, about body y with the unit level: x East, y North, z Up) moves through trapezoidal
profiles on true time τ. The unit samples at τ_k = k / (f_s (1 + ε_u)) with time stamps k / f_s; the controller
latches readings at host-driven instants and stamps them c = c₀ + (1 + ε_c) τ. The realised mapping
t_table = c₀ + (1 + ε) t_unit, 1 + ε = (1 + ε_c)/(1 + ε_u), must be found within 3σ.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from analysis.gimbal import gravity_in_body
from analysis.timebase import RunSignals, TimeBase, clock_check, estimate_time_base, misfit_cause

DEG = math.pi / 180
ACC = 80 * DEG  # rad/s²


def _profile(segments: list[tuple[float, float]]) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Piecewise-constant acceleration (duration, accel) → knot times, angles, rates, accels at the knots."""
    t, p, v = [0.0], [0.0], [0.0]
    acc = []
    for dur, a in segments:
        acc.append(a)
        p.append(p[-1] + v[-1] * dur + 0.5 * a * dur * dur)
        v.append(v[-1] + a * dur)
        t.append(t[-1] + dur)
    return np.array(t), np.array(p), np.array(v), np.array(acc + [0.0])


def _evaluate(knots: tuple[np.ndarray, ...], tau: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    t, p, v, a = knots
    i = np.clip(np.searchsorted(t, tau, side="right") - 1, 0, len(t) - 1)
    dt = tau - t[i]
    return p[i] + v[i] * dt + 0.5 * a[i] * dt * dt, v[i] + a[i] * dt


def _motions(kind: str) -> list[tuple[float, float]]:
    segs: list[tuple[float, float]] = [(5.0, 0.0)]
    if kind == "spin":
        for sign in (1, -1, 1, -1):  # 30 °/s spins both ways, 10 s each
            ramp = 30 * DEG / ACC
            segs += [(ramp, sign * ACC), (10.0, 0.0), (ramp, -sign * ACC), (6.0, 0.0)]
    else:
        for _ in range(8):  # 45° steps (triangular profile)
            half = math.sqrt(45 * DEG / ACC)
            segs += [(half, ACC), (half, -ACC), (6.0, 0.0)]
    segs.append((60.0, 0.0))
    return segs


def _bench(kind: str, seed: int, *, accel_only: bool = False) -> tuple[RunSignals, float, float]:
    rng = np.random.default_rng(seed)
    fs = 200.0
    eps_u, eps_c = rng.uniform(-100e-6, 100e-6), rng.uniform(-20e-6, 20e-6)
    c0 = rng.uniform(-0.02, 0.02)
    knots = _profile(_motions(kind))
    t_end = knots[0][-1] - 2.0
    k = np.arange(int(t_end * fs))
    tau_k = k / (fs * (1 + eps_u))
    ang, rate = _evaluate(knots, tau_k)
    angles_k = np.column_stack([np.zeros_like(ang), np.zeros_like(ang), ang])
    gyro = np.zeros((k.size, 3))
    gyro[:, 1] = rate + 0.3 * DEG / 3600 + rng.normal(0, 0.005 * DEG, k.size)  # bias + noise, rad/s
    f = gravity_in_body(angles_k, 9.81) + rng.normal(0, 3e-4, (k.size, 3))
    # readings: after every block of 40 samples, latched 2–4 ms after the block's last sample arrived
    ends = np.arange(40, k.size, 40)
    tau_l = tau_k[ends - 1] + 0.002 + rng.exponential(0.001, ends.size)
    a_l, r_l = _evaluate(knots, tau_l)
    angles = np.column_stack([np.zeros_like(a_l), np.zeros_like(a_l), a_l + rng.normal(0, 0.1 / 3600 * DEG, a_l.size)])
    rates = np.column_stack([np.zeros_like(r_l), np.zeros_like(r_l), r_l])
    sig = RunSignals(
        t=k / fs,
        accel=f,
        gyro=None if accel_only else gyro,
        table_time=c0 + (1 + eps_c) * tau_l,
        angles=angles,
        rates=rates,
        sample_index=ends,
        g=9.81,
        mounting=np.eye(3),
        latency=0.0,
    )
    return sig, c0, (1 + eps_c) / (1 + eps_u) - 1


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_gyro_estimate_finds_the_realised_offset_and_rate(seed):
    sig, c0, eps = _bench("spin", seed)
    tb = estimate_time_base(sig)
    assert tb.method == "gyro"
    assert len(tb.events) == 8  # start and stop of four spins
    assert abs(tb.offset - c0) < 3 * tb.u_offset, (tb.offset, c0, tb.u_offset)
    assert abs(tb.rate - eps) < 3 * tb.u_rate, (tb.rate, eps, tb.u_rate)
    assert tb.u_offset < 50e-6  # tens of µs from spins at 30 °/s


@pytest.mark.parametrize("seed", [4, 5])
def test_accelerometer_only_estimate_finds_the_offset_from_the_moves(seed):
    sig, c0, eps = _bench("steps", seed, accel_only=True)
    tb = estimate_time_base(sig)
    assert tb.method == "accelerometer"
    assert len(tb.events) == 8
    assert math.isfinite(tb.u_offset) and tb.u_offset < 1e-3
    assert abs(tb.offset - c0) < 3 * tb.u_offset, (tb.offset, c0, tb.u_offset)
    assert abs(tb.rate - eps) < 3 * tb.u_rate, (tb.rate, eps, tb.u_rate)


def test_mapping_round_trip_and_dict_round_trip():
    sig, _c0, _eps = _bench("spin", 7)
    tb = estimate_time_base(sig)
    t = np.array([0.0, 10.0, 100.0])
    np.testing.assert_allclose(tb.to_unit_time(tb.to_table_time(t)), t, atol=1e-12)
    back = TimeBase.from_dict(tb.as_dict())
    assert back.offset == tb.offset and back.rate == tb.rate and len(back.events) == len(tb.events)


def test_no_motion_gives_the_coarse_mapping_without_a_claimed_uncertainty():
    sig, c0, _ = _bench("spin", 8)
    still = RunSignals(**{**sig.__dict__, "angles": np.zeros_like(sig.angles), "rates": np.zeros_like(sig.rates)})
    tb = estimate_time_base(still)
    assert tb.method == "coarse" and math.isnan(tb.u_offset)
    assert abs(tb.offset - c0) < 0.01  # to within the latencies
    assert tb.notes


def test_clock_check_recovers_the_rate_from_host_times_and_flags_a_disagreement():
    rng = np.random.default_rng(3)
    eps_u, eps_c = 40e-6, -10e-6
    tu = np.arange(1, 5001) * 0.2  # unit time of each block's end
    tau = tu / (1 + eps_u)
    host_block = tau + 0.003 + rng.exponential(0.0005, tu.size)
    req = tau + 0.004
    ans = req + 0.001 + rng.exponential(0.0003, tu.size)
    ctrl = 0.01 + (1 + eps_c) * (req + 0.0005)
    truth = (1 + eps_c) / (1 + eps_u) - 1
    good = TimeBase(rate=truth, u_rate=1e-8)
    ck = clock_check(tu, host_block, ctrl, req, ans, good)
    assert abs(ck["rate"] - truth) < 5 * ck["u_rate"] and ck["consistent"]
    bad = TimeBase(rate=truth + 5e-6, u_rate=1e-8)
    assert clock_check(tu, host_block, ctrl, req, ans, bad)["consistent"] is False


def test_misfit_cause_names_host_stamped_readings():
    from analysis.timebase import TimingEvent

    res = [2e-3, -2e-3, 1.5e-3, -1e-3]
    between = [TimingEvent(float(i), 0.0, 1e-5, 2, 10, 1e-5, r) for i, r in enumerate(res)]
    tb = TimeBase(events=between, misfit=50.0, check={"reading_latency_spread_s": 1.5e-3})
    line = misfit_cause(tb, host_stamped=True, carried=1e-5)
    assert line is not None and "between motions" in line and "stamped by the host" in line
    assert "time_variable" in line and "\n" not in line
    # consistent events (Birge ratio ≤ 3) whose in-motion jitter the budget carries: nothing to say
    assert misfit_cause(TimeBase(events=between, misfit=1.0), host_stamped=True, carried=1e-3) is None
    # readings jittering within each motion by 1 ms, beyond the 10 µs the budget carries; the unit's link bursts
    within = [TimingEvent(float(i), 0.0, 1e-5, 2, 10, 1e-3, 0.0, 1e-3) for i in range(4)]
    tb = TimeBase(events=within, misfit=1.0, check={"link_latency_spread_s": 2e-3})
    line = misfit_cause(tb, host_stamped=False, carried=1e-5)
    assert line is not None and "within the motions" in line and "bursts" in line
    # neither link explains it: the time stamps are not latched with the angles
    line = misfit_cause(TimeBase(events=within, misfit=1.0), host_stamped=False, carried=1e-5)
    assert line is not None and "not latched with their angles" in line
    # the scatter in the residuals alone (jitter 0: not above the noise at rest) is never flagged
    noisy = [TimingEvent(float(i), 0.0, 1e-5, 2, 10, 1e-3, 0.0, 0.0) for i in range(4)]
    assert misfit_cause(TimeBase(events=noisy, misfit=1.0), host_stamped=True, carried=1e-5) is None


def test_excess_jitter_separates_timing_jitter_from_noise():
    from analysis.timebase.estimate import excess_jitter

    rng = np.random.default_rng(11)
    moving = np.r_[np.zeros(300, bool), np.ones(300, bool)]
    speed = 0.5  # rad/s
    noise = rng.normal(0, 1e-6, 600)  # the encoder's noise, rad, the same at rest and moving
    assert excess_jitter(noise, moving, speed) == 0.0
    jit = 2e-4  # s
    r = noise + moving * rng.normal(0, jit, 600) * speed
    assert excess_jitter(r, moving, speed) == pytest.approx(jit, rel=0.15)

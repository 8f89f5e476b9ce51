"""The soak criterion against the closed form of a first-order approach."""

from __future__ import annotations

import math

import numpy as np
import pytest

from analysis.thermal.soak import SoakCriterion, SoakMonitor


def test_settles_when_the_first_order_approach_meets_both_limits_plus_the_dwell():
    tau, step, delta, rate = 600.0, 20.0, 0.5, 0.1 / 60
    crit = SoakCriterion(tolerance=delta, rate_limit=rate, dwell=600.0, rate_window=120.0)
    mon = SoakMonitor(crit, target=300.0, start=0.0)
    t = np.arange(0.0, 4 * 3600.0, 0.1)
    x = 300.0 - step * np.exp(-t / tau)
    for i in range(0, t.size, 1000):
        if mon.feed(t[i : i + 1000], x[i : i + 1000]):
            break
    # both limits hold from the later of: |ΔT| ≤ δ and |Ṫ| = ΔT/τ ≤ rate
    t_ok = max(tau * math.log(step / delta), tau * math.log(step / (rate * tau)))
    assert mon.settled_at == pytest.approx(t_ok + 600.0, abs=70.0)  # the rate fit lags by half its window


def test_a_break_restarts_the_dwell_and_the_timeout_is_reported():
    crit = SoakCriterion(tolerance=0.5, rate_limit=0.01, dwell=100.0, timeout=400.0, rate_window=20.0)
    mon = SoakMonitor(crit, target=300.0, start=0.0)
    t = np.arange(0.0, 90.0, 0.5)
    mon.feed(t, np.full(t.size, 300.0))
    mon.feed(np.arange(90.0, 100.0, 0.5), np.full(20, 302.0))  # a jump: out of tolerance
    t2 = np.arange(100.0, 180.0, 0.5)
    mon.feed(t2, np.full(t2.size, 300.0))
    assert not mon.settled
    t3 = np.arange(180.0, 500.0, 0.5)
    mon.feed(t3, np.full(t3.size, 301.0))  # settled but out of tolerance until the time-out
    assert not mon.settled and mon.timed_out

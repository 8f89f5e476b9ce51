"""The registry's statistics against independent references: E_n by hand, ISO 5725 precision against a
one-way random-effects ANOVA (statsmodels), control limits against the textbook I-MR chart, ILAC-G24 methods."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest
import statsmodels.api as sm
from statsmodels.formula.api import ols

from benches.results.recalibration import IntervalSettings
from benches.results.registry.stats import (
    control_chart_interval,
    control_limits,
    in_tolerance,
    normalised_error,
    precision,
    staircase,
)


def test_normalised_error():
    assert normalised_error(10.0, 3.0, 14.0, 4.0) == pytest.approx(4.0 / 5.0)  # 3-4-5
    assert normalised_error(1.0, 0.0, 1.0, 0.0) == 0.0
    assert math.isinf(normalised_error(1.0, 0.0, 2.0, 0.0))


def test_precision_matches_a_one_way_anova_unbalanced():
    rng = np.random.default_rng(11)
    sizes = [4, 7, 3, 5]
    bench_effects = rng.normal(0.0, 2.0, len(sizes))
    groups = [list(e + rng.normal(0.0, 1.0, n)) for e, n in zip(bench_effects, sizes, strict=True)]
    pr = precision(groups)
    df = pd.DataFrame({"y": [v for g in groups for v in g],
                       "bench": [str(i) for i, g in enumerate(groups) for _ in g]})  # fmt: skip
    table = sm.stats.anova_lm(ols("y ~ C(bench)", data=df).fit())
    ms_between, ms_within = table["mean_sq"].iloc[0], table["mean_sq"].iloc[1]
    n = np.array(sizes)
    n0 = (n.sum() - (n**2).sum() / n.sum()) / (len(n) - 1)  # ISO 5725-2 / the classic unbalanced n0
    assert pr.s_r == pytest.approx(math.sqrt(ms_within), rel=1e-12)
    s_l2 = max(0.0, (ms_between - ms_within) / n0)
    assert pr.s_L == pytest.approx(math.sqrt(s_l2), rel=1e-12)
    assert pr.s_R == pytest.approx(math.sqrt(s_l2 + ms_within), rel=1e-12)
    assert (pr.benches, pr.calibrations, pr.dof_r) == (4, 19, 15)


def test_precision_with_one_bench_has_repeatability_only():
    pr = precision([[1.0, 2.0, 4.0]])
    assert pr.s_r == pytest.approx(np.std([1.0, 2.0, 4.0], ddof=1)) and pr.s_R is None and pr.s_L is None
    assert precision([[1.0]]).s_r is None


def test_control_limits_are_the_individuals_chart():
    x = [10.0, 12.0, 11.0, 15.0, 13.0]
    lim = control_limits(x)
    mr_bar = (2 + 1 + 4 + 2) / 4
    assert lim.centre == pytest.approx(12.2) and lim.sigma == pytest.approx(mr_bar / 1.128)
    assert lim.action[1] == pytest.approx(12.2 + 3 * mr_bar / 1.128)
    assert control_limits([1.0, 2.0]) is None


def test_staircase_extends_when_found_in_tolerance_and_reduces_otherwise_within_bounds():
    s = IntervalSettings(initial_days=360, min_days=90, max_days=720, extend=1.5, reduce=0.5)
    assert staircase([], s) == 360
    assert staircase([True], s) == 540
    assert staircase([True, True], s) == 720  # capped
    assert staircase([True, True, False], s) == 360
    assert staircase([False, False, False], s) == 90  # floored


def test_in_tolerance_uses_en_of_identified_parameters_and_the_decision():
    x0, u = np.array([0.0, 0.0]), np.array([1.0, 1.0])
    ident = np.array([True, False])
    assert in_tolerance(x0, u, np.array([1.4, 99.0]), u, ident, "PASS")  # E_n 0.99; the second not identified
    assert not in_tolerance(x0, u, np.array([1.5, 0.0]), u, ident, "PASS")
    assert not in_tolerance(x0, u, x0, u, ident, "FAIL")


def test_control_chart_interval_is_the_time_to_use_up_the_allowance():
    s = IntervalSettings(min_days=10, max_days=2000, drift_allowance_U=1.0)
    days = [0.0, 100.0, 200.0, 300.0]
    values = [0.0, 1.0, 2.0, 3.0]  # 0.01 per day, no scatter
    d = control_chart_interval("b_x", days, values, 2.0, s)
    assert d.rate_per_day == pytest.approx(0.01) and d.scatter == pytest.approx(0.0, abs=1e-12)
    assert d.interval_days == pytest.approx(200.0)
    flat = control_chart_interval("b_x", days, [1.0, 1.0, 1.0, 1.0], 2.0, s)
    assert flat.interval_days == 2000
    assert control_chart_interval("b_x", days[:2], values[:2], 2.0, s) is None

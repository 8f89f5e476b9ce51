"""analysis.units: the one rule for values too large to analyse."""

from __future__ import annotations

import numpy as np

from analysis.units import MAX_MAGNITUDE, magnitude_problem


def test_magnitude_problem_names_the_largest_value_its_sample_and_the_limit():
    x = np.array([1.0, np.nan, -3e101, 2e101])
    msg = magnitude_problem(x, "variance")
    assert msg is not None
    assert "3e+101" in msg and "(sample 2)" in msg and "variance sums" in msg and f"{MAX_MAGNITUDE:.0e}" in msg


def test_magnitude_problem_accepts_the_limit_gaps_and_empty_records():
    assert magnitude_problem(np.array([MAX_MAGNITUDE, -MAX_MAGNITUDE, np.nan]), "periodic") is None
    assert magnitude_problem(np.full(3, np.nan), "periodic") is None
    assert magnitude_problem(np.zeros(0), "periodic") is None

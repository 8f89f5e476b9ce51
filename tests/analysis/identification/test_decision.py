"""Decision rule (analysis.identification.decision): ILAC-G8 non-binary statement with guard band U."""

from __future__ import annotations

import math

import pytest

from analysis.identification.decision import (
    FAIL,
    INVALID,
    NO_LIMIT,
    NOT_EVALUATED,
    PASS,
    UNDECIDED,
    decide,
    overall_verdict,
)


@pytest.mark.parametrize(
    ("value", "u_exp", "limit", "expected"),
    [
        (1.0, 0.5, 2.0, PASS),  # 1.5 ≤ 2
        (-1.0, 0.5, 2.0, PASS),  # symmetric limit on |x|
        (1.8, 0.5, 2.0, UNDECIDED),  # inside, U straddles (conditional pass)
        (2.2, 0.5, 2.0, UNDECIDED),  # outside, U straddles (conditional fail)
        (0.0, 2.5, 2.0, UNDECIDED),  # U ≥ L: no outcome can show conformity
        (3.0, 0.5, 2.0, FAIL),  # 2.5 > 2
        (1.0, 0.5, None, NO_LIMIT),
    ],
)
def test_per_parameter_verdicts(value, u_exp, limit, expected):
    assert decide(value, u_exp, limit).verdict == expected


def test_undecided_says_on_which_side_the_estimate_lies():
    assert "inside" in decide(1.8, 0.5, 2.0).reason and "outside" in decide(2.2, 0.5, 2.0).reason


@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf, 1.7e308 * 10])
def test_non_finite_estimate_or_uncertainty_is_invalid_never_pass(bad):
    assert decide(bad, 0.1, 2.0).verdict == INVALID
    assert decide(0.1, bad, 2.0).verdict == INVALID
    # a NaN comparison is false: a naive rule would have passed it
    assert overall_verdict([decide(0.1, bad, 2.0).verdict, PASS], [True, True]) == "INVALID"


def test_integrity_failure_and_rank_deficiency_can_never_pass():
    assert decide(0.0, 0.1, 2.0, integrity_ok=False).verdict == INVALID
    assert decide(0.0, 0.1, 2.0, full_rank=False).verdict == INVALID
    assert overall_verdict([PASS, PASS], [True, True], integrity_ok=False) == "INVALID"
    assert overall_verdict([PASS, PASS], [True, True], full_rank=False) == "INCONCLUSIVE"


def test_not_evaluated_is_distinct_from_undecided():
    c = decide(0.03, 0.001, 0.06, identified=False)
    assert c.verdict == NOT_EVALUATED and "cannot identify" in c.reason
    assert overall_verdict([PASS, NOT_EVALUATED], [True, True]) == "INCONCLUSIVE"
    # not evaluated without a limit does not make the result inconclusive
    assert overall_verdict([PASS, NOT_EVALUATED], [True, False]) == "PASS"
    assert overall_verdict([PASS, UNDECIDED], [True, True]) == "INCONCLUSIVE"


def test_overall_order_of_precedence():
    assert overall_verdict([FAIL, UNDECIDED, INVALID], [True] * 3) == "INVALID"
    assert overall_verdict([FAIL, UNDECIDED], [True] * 2, complete=False) == "FAIL"
    assert overall_verdict([PASS, UNDECIDED], [True] * 2, complete=False) == "INCOMPLETE"
    assert overall_verdict([NO_LIMIT, NO_LIMIT], [False, False]) == "NO LIMITS"
    with pytest.raises(ValueError):
        overall_verdict(["PASS (conditional)"], [True])

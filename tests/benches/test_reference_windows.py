"""The reference's interpolation rule (benches.reference.interpolate_windows, the one place it is written) on its
edge cases: against a plain per-sample reading of the rule written here, and its many-windows form against its
one-window form (benches.reference.interpolate_table) window by window.

Edge cases: before a span's first reading, after its last, exactly at a reading, between two readings, no reading
inside the span (the last one at or before its start; the table's first if none is), all readings (span None), a
NaN sample time (NaN), a reading with a NaN time (no reading), readings out of time order, equal reading times.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from benches.reference import interpolate_table, interpolate_windows


def _plain(t, tt, ta, tr, span):
    """The rule as prose says it, one sample at a time (distinct reading times)."""
    order = sorted((i for i in range(len(tt)) if not math.isnan(tt[i])), key=lambda i: tt[i])
    keep = [i for i in order if span is None or span[0] <= tt[i] <= span[1]]
    if not keep:
        before = [i for i in order if tt[i] <= span[0]]
        keep = [before[-1] if before else order[0]]
    ang, rat = np.empty((len(t), 3)), np.empty((len(t), 3))
    for n, x in enumerate(t):
        first, last = keep[0], keep[-1]
        if math.isnan(x):
            ang[n], rat[n] = np.nan, np.nan
        elif x < tt[first]:
            ang[n], rat[n] = ta[first] + (x - tt[first]) * tr[first], tr[first]
        elif x > tt[last]:
            ang[n], rat[n] = ta[last] + (x - tt[last]) * tr[last], tr[last]
        else:
            k = max(m for m in range(len(keep)) if tt[keep[m]] <= x)
            i = keep[k]
            if x == tt[i]:
                ang[n], rat[n] = ta[i], tr[i]
            else:
                j = keep[k + 1]
                w = (x - tt[i]) / (tt[j] - tt[i])
                ang[n], rat[n] = ta[i] + w * (ta[j] - ta[i]), tr[i] + w * (tr[j] - tr[i])
    return ang, rat


def _table(rng: np.random.Generator, n: int):
    tt = np.cumsum(rng.uniform(0.005, 0.02, n))
    return tt, np.cumsum(rng.normal(0.0, 0.01, (n, 3)), axis=0), rng.normal(0.0, 0.5, (n, 3))


def _windows(rng: np.random.Generator, tt, count: int):
    """Windows with every edge case: spans over readings, beyond the table's ends, between two readings, None;
    samples before, inside and after the span, some exactly at reading times, one NaN."""
    tq, spans = [], []
    for w in range(count):
        a, b = np.sort(rng.uniform(tt[0] - 0.5, tt[-1] + 0.5, 2))
        kind = w % 5
        if kind == 1:  # between two readings: none inside the span
            k = int(rng.integers(0, tt.size - 1))
            a, b = (tt[k] + tt[k + 1]) / 2 - 1e-4, (tt[k] + tt[k + 1]) / 2 + 1e-4
        elif kind == 2:  # before the table: no reading at or before the start either
            a, b = tt[0] - 1.0, tt[0] - 0.5
        elif kind == 3:  # after the table
            a, b = tt[-1] + 0.5, tt[-1] + 1.0
        q = np.sort(rng.uniform(a - 0.1, b + 0.1, int(rng.integers(1, 40))))
        q = np.sort(np.concatenate([q, tt[rng.integers(0, tt.size, 3)], [tt[0], tt[-1]]]))  # at readings exactly
        if w == 7:
            q[q.size // 2] = np.nan
        tq.append(q)
        spans.append(None if kind == 4 else (float(a), float(b)))
    return tq, spans


def test_the_rule_against_a_plain_reading_of_it() -> None:
    rng = np.random.default_rng(11)
    tt, ta, tr = _table(rng, 60)
    tq, spans = _windows(rng, tt, 25)
    for q, s in zip(tq, spans, strict=True):
        ang, rat = interpolate_table(q, tt, ta, tr, s)
        ref_a, ref_r = _plain(q, tt, ta, tr, s)
        np.testing.assert_allclose(ang, ref_a, rtol=0, atol=1e-12)
        np.testing.assert_allclose(rat, ref_r, rtol=0, atol=1e-12)
        at = np.isin(q, tt[(tt >= s[0]) & (tt <= s[1])] if s is not None else tt)
        np.testing.assert_array_equal(ang[at], ta[np.searchsorted(tt, q[at])])  # at a reading: that reading
    # readings out of time order, and readings with a NaN time, change nothing
    p = rng.permutation(tt.size)
    tt_nan = np.concatenate([tt[p], [np.nan, np.nan]])
    ta_nan, tr_nan = np.concatenate([ta[p], ta[:2] + 5.0]), np.concatenate([tr[p], tr[:2] + 5.0])
    for q, s in zip(tq, spans, strict=True):
        got, want = interpolate_table(q, tt_nan, ta_nan, tr_nan, s), interpolate_table(q, tt, ta, tr, s)
        np.testing.assert_array_equal(got[0], want[0])
        np.testing.assert_array_equal(got[1], want[1])


def test_many_windows_give_what_one_window_gives_per_window() -> None:
    rng = np.random.default_rng(7)
    for trial in range(20):
        tt, ta, tr = _table(rng, int(rng.integers(2, 300)))
        if trial % 2 == 0:  # equal reading times, among them the table's first two
            tt[1] = tt[0]
            k = int(rng.integers(2, tt.size)) if tt.size > 2 else 1
            tt[k] = tt[k - 1]
        tq, spans = _windows(rng, tt, int(rng.integers(1, 15)))
        ang, rat = interpolate_windows(tq, spans, tt, ta, tr)
        one = [interpolate_table(q, tt, ta, tr, s) for q, s in zip(tq, spans, strict=True)]
        np.testing.assert_array_equal(ang, np.concatenate([o[0] for o in one]))
        np.testing.assert_array_equal(rat, np.concatenate([o[1] for o in one]))


def test_no_readings_is_refused() -> None:
    for tt in (np.empty(0), np.array([np.nan, np.nan])):
        with pytest.raises(ValueError, match="no table readings"):
            interpolate_table(np.array([1.0]), tt, np.zeros((tt.size, 3)), np.zeros((tt.size, 3)))

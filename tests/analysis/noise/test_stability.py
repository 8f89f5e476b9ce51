"""The stability family (analysis/noise/stability.py): every estimator equals allantools on the same data."""

from __future__ import annotations

import allantools
import numpy as np
import pytest

from analysis.noise.stability import ESTIMATORS, m_grid, stability

_ALL = tuple(e for e in ESTIMATORS if e not in ("theoh", "theobr"))  # not in allantools (tested below)


def _record(n: int, c: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    y = rng.normal(size=(n, c)) + 0.05 * np.cumsum(rng.normal(size=(n, c)), axis=0)
    return y + np.linspace(0.0, 0.3, n)[:, None] + 2.0


def _compare(data: np.ndarray, rate: float, data_type: str, res, rtol: float = 1e-10) -> None:
    for name in _ALL:
        est = res.estimates[name]
        for ch in range(data.shape[1]):
            keep = np.isfinite(est.dev[:, ch])
            assert keep.sum() >= 3, name
            tt, dev, _, ns = getattr(allantools, name)(data[:, ch], rate=rate, data_type=data_type, taus=est.tau[keep])
            np.testing.assert_allclose(est.tau[keep], tt, rtol=1e-15, err_msg=name)
            np.testing.assert_allclose(est.dev[keep, ch], dev, rtol=rtol, err_msg=f"{name} ch{ch}")
            np.testing.assert_array_equal(est.n_terms[keep, ch], ns.astype(np.int64), err_msg=f"{name} n")


@pytest.mark.parametrize("data_type", ["freq", "phase"])
def test_every_estimator_equals_allantools_every_m(data_type: str) -> None:
    """All m of a short two-channel record (every reflected/edge case of the total family), freq and phase."""
    y = _record(150, 2, seed=1)
    rate = 4.0
    data = y if data_type == "freq" else np.cumsum(y, axis=0) / rate
    res = stability(data, rate, _ALL, "all", data_type, confidence=None)
    _compare(data, rate, data_type, res)


def test_every_estimator_equals_allantools_octave_and_decade() -> None:
    y = _record(700, 1, seed=2)
    for grid in ("octave", "decade"):
        res = stability(y, 10.0, _ALL, grid, "freq", confidence=None)
        _compare(y, 10.0, "freq", res)


def test_gaps_skip_the_terms_that_touch_them_like_allantools_gradev() -> None:
    """Phase data with NaN points: ADEV/OADEV use only terms whose three points are finite, as gradev."""
    rng = np.random.default_rng(3)
    x = np.cumsum(rng.normal(size=2000)) * 1e-3
    x[[100, 101, 102, 777, 1500]] = np.nan
    res = stability(x, 1.0, ("oadev", "adev", "mdev", "totdev", "mtotdev", "theo1"), "octave", "phase", confidence=None)
    assert int(res.gap_samples[0]) == 5 and int(res.gap_runs[0]) == 3
    oadev = res.estimates["oadev"]
    tt, dev, _, ns = allantools.gradev(x, rate=1.0, data_type="phase", taus=oadev.tau)
    np.testing.assert_allclose(oadev.dev[:, 0], dev, rtol=1e-12)
    np.testing.assert_array_equal(oadev.n_terms[:, 0], ns.astype(np.int64))
    # span estimators: the count drops by the terms whose span holds a gap, and the values stay finite
    full = stability(np.nan_to_num(x), 1.0, ("mdev", "mtotdev", "theo1"), "octave", "phase", confidence=None)
    for name in ("mdev", "mtotdev", "theo1"):
        e, f = res.estimates[name], full.estimates[name]
        assert np.all(e.n_terms[:, 0] < f.n_terms[:, 0]) and np.all(np.isfinite(e.dev[:4, 0])), name


def test_frequency_gap_equals_the_definition_on_the_remaining_terms() -> None:
    """Frequency input: a NaN sample removes exactly the second differences whose span holds it."""
    rng = np.random.default_rng(4)
    y = rng.normal(size=1000)
    y[500] = np.nan
    res = stability(y, 1.0, ("oadev",), [1.0, 7.0, 30.0], "freq", confidence=None)
    yy = y - np.nanmean(y)
    x = np.concatenate([[0.0], np.cumsum(np.nan_to_num(yy))])
    for j, m in enumerate((1, 7, 30)):
        i = np.arange(x.size - 2 * m)
        ok = ~((i <= 500) & (500 < i + 2 * m))
        d = (x[i + 2 * m] - 2 * x[i + m] + x[i])[ok]
        assert res.estimates["oadev"].n_terms[j, 0] == ok.sum()
        np.testing.assert_allclose(res.estimates["oadev"].dev[j, 0], np.sqrt(np.mean(d**2) / (2 * m * m)), rtol=1e-12)


def test_channels_are_independent() -> None:
    y = _record(800, 3, seed=5)
    both = stability(y, 1.0, _ALL, "octave", "freq", confidence=None)
    one = stability(y[:, 1], 1.0, _ALL, "octave", "freq", confidence=None)
    for name in _ALL:
        np.testing.assert_allclose(both.estimates[name].dev[:, 1], one.estimates[name].dev[:, 0], rtol=1e-12)


def test_theoh_stitches_oadev_and_theobr() -> None:
    """TheoH: OADEV for m < k (k = split·T), TheoBR = Theo1·√kf at 0.75 m ≥ k, kf the mean OAVAR(9+3i)/Theo1(12+4i)
    over i = 0 … ⌊N/6⌋ − 3, each recomputed here with allantools."""
    y = _record(600, 1, seed=6)
    res = stability(y, 1.0, ("theoh", "theobr", "oadev", "theo1"), "all", "freq", confidence=None, theoh_split=0.1)
    th = res.estimates["theoh"]
    avar_part = th.tau < 59.9
    o = res.estimates["oadev"]
    np.testing.assert_allclose(th.dev[avar_part, 0], o.dev[np.isin(o.m, th.m[avar_part]), 0], rtol=1e-12)
    i = np.arange(601 // 6 - 3 + 1)  # 601 phase points; the last AVAR (m = 300) has a single term and is skipped
    ta, a, _, na = allantools.oadev(y, rate=1.0, data_type="freq", taus=9.0 + 3 * i)
    tt, t, _, _ = allantools.theo1(y, rate=1.0, data_type="freq", taus=12.0 + 4 * i)
    assert list(ta) == list(9.0 + 3 * i[:-1]) and list(tt) == list(12.0 + 4 * i) and na[-1] > 1
    kf = np.mean((a / t[:-1]) ** 2)
    t1 = res.estimates["theo1"]
    np.testing.assert_allclose(th.tau[~avar_part], 0.75 * th.m[~avar_part])
    assert np.all(0.75 * th.m[~avar_part] >= 60) and np.all(th.m[avar_part] < 60)
    want = t1.dev[np.isin(t1.m, th.m[~avar_part]), 0] * np.sqrt(kf)
    np.testing.assert_allclose(th.dev[~avar_part, 0], want, rtol=1e-9)
    br = res.estimates["theobr"]
    np.testing.assert_allclose(br.dev[:, 0], t1.dev[:, 0] * np.sqrt(kf), rtol=1e-9)
    np.testing.assert_allclose(br.tau, 0.75 * t1.m)


def test_grids_and_bad_input() -> None:
    assert list(m_grid(1000, "decade", 1.0)) == [1, 2, 4, 10, 20, 40, 100, 200, 400]
    assert list(m_grid(20, "octave", 1.0)) == [1, 2, 4, 8, 16]
    assert list(m_grid(1000, [0.5, 1.0, 1.1], 2.0)) == [1, 2]
    with pytest.raises(ValueError, match="unknown estimator"):
        stability(np.ones(100), 1.0, ("avar",))
    with pytest.raises(ValueError, match="data_type"):
        stability(np.ones(100), 1.0, ("adev",), data_type="time")
    with pytest.raises(ValueError, match="inf"):
        stability(np.array([1.0, np.inf] * 50), 1.0, ("adev",))
    with pytest.raises(ValueError, match="no finite"):
        stability(np.full(100, np.nan), 1.0, ("adev",))

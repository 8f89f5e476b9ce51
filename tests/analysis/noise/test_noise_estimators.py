"""Allan-family estimators (analysis/noise/allan.py): equality with allantools, precision, EDF, the "improved" form."""

from __future__ import annotations

import allantools
import numpy as np
import pytest

from analysis.noise.allan import ESTIMATORS, allan_variances, improved_total_variance, tau_grid

_AT = {"avar": "adev", "oavar": "oadev", "totvar": "totdev", "mvar": "mdev"}


def _compare(y: np.ndarray, rate: float, res, rtol: float = 1e-10) -> None:
    """Every estimator of ``res`` equals allantools on every channel where allantools defines it (n > 1)."""
    y2 = y if y.ndim == 2 else y[:, None]
    for est, fname in _AT.items():
        for ch in range(y2.shape[1]):
            tt, dev, _, _ = getattr(allantools, fname)(y2[:, ch], rate=rate, data_type="freq", taus=res.tau)
            keep = res.n_terms[est] > 1
            np.testing.assert_allclose(res.tau[keep], tt, rtol=1e-15)
            np.testing.assert_allclose(np.sqrt(res.var[est][keep, ch]), dev, rtol=rtol, err_msg=f"{est} ch{ch}")


@pytest.mark.parametrize("taus", ["octave", "log"])
def test_equals_allantools_on_coloured_multichannel_data(taus: str) -> None:
    rng = np.random.default_rng(11)
    n, rate = 30011, 200.0
    white = rng.normal(size=(n, 3)) * [1e-3, 2e-3, 5e-4]
    rw = np.cumsum(rng.normal(size=(n, 3)), axis=0) * 1e-6
    y = white + rw + np.array([0.3, -2.0, 9.81])
    res = allan_variances(y, rate, taus, chunk=4096)  # small chunks: many chunk boundaries in the test
    assert res.tau.size > 10
    _compare(y, rate, res)


def test_equals_allantools_every_m_up_to_n_on_a_short_ramped_record() -> None:
    rng = np.random.default_rng(3)
    n, rate = 257, 10.0
    y = rng.normal(size=n) + 0.05 * np.arange(n) + 4.0
    res = allan_variances(y, rate, "all", max_m=n)
    _compare(y, rate, res, rtol=1e-9)  # allantools' own mdev running sum rounds at ~1e-11 here


def test_ramp_dominated_record_keeps_precision() -> None:
    """A strong ramp plus tiny noise: the analytic ramp handling keeps σ² = R²τ²/2 + noise exact at small τ."""
    rng = np.random.default_rng(4)
    n, rate, r = 400_000, 100.0, 1e-3
    t = np.arange(n) / rate
    y = r * t
    res = allan_variances(y, rate)
    for est in ("avar", "oavar", "mvar"):
        np.testing.assert_allclose(res.var[est][:, 0], r**2 * res.tau**2 / 2, rtol=1e-9)
    # with noise: compare with the definitions evaluated in extended precision (allantools' own running sums
    # lose ~1e-3 on the modified AVAR of this record, so it cannot be the reference here)
    y2 = y + rng.normal(size=n) * 1e-6
    ms = np.array([1, 10, 100])
    res2 = allan_variances(y2, rate, ms / rate)
    x = np.concatenate([[0.0], np.cumsum(y2.astype(np.longdouble) - np.mean(y2, dtype=np.longdouble))]) / rate
    for j, m in enumerate(ms):
        tau = m / rate
        d = x[2 * m :] - 2 * x[m:-m] + x[: -2 * m]
        np.testing.assert_allclose(res2.var["oavar"][j, 0], float(np.mean(d**2) / (2 * tau**2)), rtol=1e-9)
        cd = np.concatenate([[0.0], np.cumsum(d)])
        inner = cd[m:] - cd[:-m]
        np.testing.assert_allclose(res2.var["mvar"][j, 0], float(np.mean(inner**2) / (2 * m**2 * tau**2)), rtol=1e-9)


def test_tau_grids() -> None:
    assert list(tau_grid(100, 1.0, "octave")) == [1, 2, 4, 8, 16, 32]
    assert tau_grid(100, 1.0, "all").max() == 33
    lg = tau_grid(10**6, 100.0, "log", points_per_decade=10)
    assert lg[0] == 1 and np.all(np.diff(lg) > 0) and lg[-1] <= 10**6 // 3
    assert list(tau_grid(1000, 10.0, [0.1, 0.1, 1.0, 1e6])) == [1, 10]
    with pytest.raises(ValueError, match="unknown τ grid"):
        tau_grid(100, 1.0, "weekly")


@pytest.mark.parametrize(
    ("data", "rate", "match"),
    [
        (np.ones(3), 1.0, "too short"),
        (np.array([1.0, np.nan, 2.0, 3.0, 4.0]), 1.0, "NaN"),
        (np.ones(100), 0.0, "positive"),
        (np.ones(100), float("nan"), "positive"),
        (np.array(["a"] * 10), 1.0, "numeric"),
    ],
)
def test_bad_input_is_a_clear_error(data: np.ndarray, rate: float, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        allan_variances(data, rate)


def _mc_white(runs: int, n: int, m: int, seed: int) -> dict[str, np.ndarray]:
    rng = np.random.default_rng(seed)
    y = rng.normal(size=(n, runs))
    res = allan_variances(y, 1.0, [float(m)])
    out = {k: res.var[k][0] for k in ESTIMATORS}
    out["itotvar"] = improved_total_variance(y, 1.0, [float(m)]).var["itotvar"][0]
    out["edf_avar"] = res.edf["avar"][0]
    return out


def test_white_noise_scatter_edf_and_unbiasedness() -> None:
    """White FM: AVAR deviation scatter ≈ √(3/(4(K−1))) (not 1/√(2(K−1))); total variance unbiased and tighter;
    the published "improved total variance" no tighter than AVAR."""
    n, m, runs = 4096, 64, 600
    r = _mc_white(runs, n, m, seed=7)
    true = 1.0 / m  # σ² of white FM with unit variance per sample
    k = n // m
    rel_adev = np.std(np.sqrt(r["avar"] / true))
    spec, naive = np.sqrt(3 / (4 * (k - 1))), 1 / np.sqrt(2 * (k - 1))
    assert rel_adev == pytest.approx(spec, rel=0.1)
    assert abs(rel_adev - spec) < abs(rel_adev - naive)
    # EDF used for the CI reproduces that scatter: Var(σ²)/σ⁴ = 2/EDF
    np.testing.assert_allclose(np.var(r["avar"] / true), 2 / r["edf_avar"].mean(), rtol=0.25)
    for est in ("avar", "oavar", "totvar"):
        assert np.mean(r[est]) / true == pytest.approx(1.0, abs=4 * np.std(r[est] / true) / np.sqrt(runs))
    assert np.std(r["totvar"]) < 0.8 * np.std(r["avar"])
    assert np.std(r["itotvar"]) > 0.8 * np.std(r["avar"])


def test_confidence_interval_coverage_white_noise() -> None:
    """The 68.3 % χ² interval of OADEV covers the true deviation in ≈ 68 % of white-noise records."""
    rng = np.random.default_rng(21)
    n, runs = 4096, 300
    y = rng.normal(size=(n, runs))
    res = allan_variances(y, 1.0, [1.0, 8.0, 64.0, 512.0])
    true = np.sqrt(1.0 / res.m)[:, None]
    cover = (res.lo["oavar"] <= true) & (true <= res.hi["oavar"])
    np.testing.assert_allclose(cover.mean(axis=1), 0.683, atol=0.09)
    assert np.all(res.alpha[:3] == 0)


def test_improved_total_variance_reproduces_the_published_formula() -> None:
    """Direct evaluation of eqs. 10–11 on a small record, independent of the vectorised code."""
    rng = np.random.default_rng(5)
    n = 40
    y = rng.normal(size=n)
    ext = np.concatenate([y[: n // 2][::-1], y, y[n - (n - n // 2) :][::-1]])
    for m in (1, 2, 4, 8):
        blocks = [ext[k * m : (k + 1) * m] for k in range(len(ext) // m)]
        dk = [(blocks[k].sum() - blocks[k - 1].sum()) ** 2 / m**2 for k in range(1, len(blocks))]
        expect = sum(dk) / (2 * (2 * n / m - 2))
        got = improved_total_variance(y, 1.0, [float(m)]).var["itotvar"][0, 0]
        assert got == pytest.approx(expect, rel=1e-12)

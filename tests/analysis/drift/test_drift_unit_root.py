"""ADF and KPSS (analysis/drift/unit_root.py) against statsmodels' adfuller and kpss on the reference series."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from analysis.drift.preprocess import DriftInputError
from analysis.drift.unit_root import adf_test, kpss_test
from tests import REPO_ROOT

DATA = REPO_ROOT / "tests" / "data" / "drift"


def _series() -> dict[str, np.ndarray]:
    ys = np.genfromtxt(DATA / "gretl_arma_series.csv", delimiter=",", names=True)
    out = {f"gretl_{k}": np.asarray(ys[k], dtype=np.float64) for k in ys.dtype.names}
    cpi = np.loadtxt(DATA / "cpi.csv", skiprows=1)
    wpi = np.loadtxt(DATA / "wpi.csv", skiprows=1)
    out.update(cpi=cpi, dcpi=np.diff(cpi), wpi=wpi, dwpi=np.diff(wpi))
    out["lake"] = np.loadtxt(DATA / "lake.csv", skiprows=1)
    out["sunspots"] = np.loadtxt(DATA / "sunspots.csv", skiprows=1, delimiter=",")[:, 0]
    rng = np.random.default_rng(7)
    out["white_5000"] = rng.normal(size=5000)
    out["random_walk_20000"] = np.cumsum(rng.normal(size=20_000))  # several QR row blocks
    return out


SERIES = _series()


@pytest.mark.parametrize("name", sorted(SERIES))
@pytest.mark.parametrize(("regression", "autolag"), [("c", "aic"), ("ct", "aic"), ("n", "bic"), ("c", None)])
def test_adf_equals_statsmodels(name: str, regression: str, autolag: str | None) -> None:
    from statsmodels.tsa.stattools import adfuller

    x = SERIES[name]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        ref = adfuller(x, regression=regression, autolag=None if autolag is None else autolag.upper())
    got = adf_test(x, regression, autolag)
    assert got.extra["used_lag"] == ref[2] and got.extra["nobs"] == ref[3]
    assert got.statistic == pytest.approx(ref[0], rel=1e-8, abs=1e-10)
    assert got.p_value == pytest.approx(ref[1], rel=1e-8, abs=1e-12)
    for k, v in ref[4].items():
        assert got.extra["critical_values"][k] == pytest.approx(v, rel=1e-12)
    if autolag is not None:
        assert got.extra["ic_best"] == pytest.approx(ref[5], rel=1e-8)


@pytest.mark.parametrize("name", sorted(SERIES))
@pytest.mark.parametrize(("regression", "nlags"), [("c", "auto"), ("ct", "auto"), ("c", "legacy"), ("c", 3)])
def test_kpss_equals_statsmodels(name: str, regression: str, nlags: str | int) -> None:
    from statsmodels.tsa.stattools import kpss

    x = SERIES[name]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        stat, p, lags, crit = kpss(x, regression=regression, nlags=nlags)
    got = kpss_test(x, regression, nlags)
    assert got.extra["lags"] == lags
    assert got.statistic == pytest.approx(stat, rel=1e-8)
    assert got.p_value == pytest.approx(p, rel=1e-8)
    assert got.extra["critical_values"] == crit


def test_verdicts_on_white_noise_and_a_random_walk() -> None:
    assert adf_test(SERIES["white_5000"]).verdict == "pass"  # unit root rejected
    assert kpss_test(SERIES["white_5000"]).verdict == "pass"
    assert adf_test(SERIES["random_walk_20000"]).verdict == "reject"
    assert kpss_test(SERIES["random_walk_20000"]).verdict == "reject"


def test_bad_input_refused() -> None:
    with pytest.raises(DriftInputError):
        adf_test(np.ones(100))
    with pytest.raises(DriftInputError):
        kpss_test([1.0, 2.0])
    with pytest.raises(DriftInputError):
        adf_test(np.arange(50.0), regression="ctt")

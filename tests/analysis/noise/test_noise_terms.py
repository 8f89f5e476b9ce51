"""Noise-term fit (analysis/noise/terms.py): the acceptance checks of spec/noise-variance.md on synthetic data."""

from __future__ import annotations

import math

import numpy as np
import pytest

from analysis import units
from analysis.noise.allan import allan_variances
from analysis.noise.slope import slope_readings
from analysis.noise.terms import (
    B_FLOOR,
    FIT_ESTIMATORS,
    GAINS,
    analyse_noise,
    fit_noise_terms,
    to_display,
)
from tests.noise_synth import pink


def _fit(y: np.ndarray, rate: float, taus: str = "octave"):
    res = allan_variances(y, rate, taus)
    return res, fit_noise_terms(res.tau, res.var["oavar"][:, 0], y.shape[0] / rate, res.edf["oavar"][:, 0])


def test_white_noise_gives_n_within_2_percent() -> None:
    rng = np.random.default_rng(101)
    rate, sw = 200.0, 0.003  # rad/s per sample
    y = rng.normal(0.0, sw, 10**6)
    _, fit = _fit(y, rate)
    n_true = sw * math.sqrt(1.0 / rate)
    n, s = fit.terms["N"]
    assert n == pytest.approx(n_true, rel=0.02)
    assert abs(n - n_true) < 4 * s  # the quoted uncertainty is not absurdly small
    assert all(fit.coefficients >= 0)


def test_differenced_white_angle_noise_gives_q_within_2_percent() -> None:
    rng = np.random.default_rng(102)
    rate, q = 100.0, 2e-5  # rad
    theta = rng.normal(0.0, q, 10**6 + 1)
    y = np.diff(theta) * rate
    res, fit = _fit(y, rate)
    assert fit.terms["Q"][0] == pytest.approx(q, rel=0.02)
    np.testing.assert_allclose(np.sqrt(res.var["oavar"][:4, 0]), math.sqrt(3) * q / res.tau[:4], rtol=0.02)
    assert np.all(res.alpha[:4, 0] >= 1)  # identified as phase noise


def test_uniform_quantisation_gives_lsb_over_sqrt12() -> None:
    """Quantisation error of an angle that moves many LSB per sample: Q = LSB/√12 (not LSB²/2)."""
    rng = np.random.default_rng(103)
    rate, lsb = 100.0, 1e-6
    theta = np.cumsum(rng.normal(0.0, 37.3 * lsb, 10**6 + 1))
    err = np.round(theta / lsb) * lsb - theta
    y = np.diff(err) * rate
    _, fit = _fit(y, rate)
    assert fit.terms["Q"][0] == pytest.approx(lsb / math.sqrt(12.0), rel=0.02)


def test_rate_ramp_exact() -> None:
    rate, r = 50.0, 3e-6  # rad/s²
    t = np.arange(200_000) / rate
    y = 1e-3 + r * t
    _, fit = _fit(y, rate)
    assert fit.terms["R"][0] == pytest.approx(r, rel=1e-6)


def test_pink_noise_floor_and_bias_instability_within_15_percent() -> None:
    rng = np.random.default_rng(104)
    rate, b = 100.0, 1e-5
    y = pink(2**20, rate, b, rng)
    res, fit = _fit(y, rate)
    mid = (res.tau > 1.0) & (res.tau < 300.0)
    np.testing.assert_allclose(np.sqrt(res.var["oavar"][mid, 0]), B_FLOOR * b, rtol=0.2)
    assert fit.terms["B"][0] == pytest.approx(b, rel=0.15)
    reading = slope_readings(res.tau, np.sqrt(res.var["oavar"][:, 0]), res.m, y.size + 1, "oadev", GAINS)["B"]
    assert reading["value"] == pytest.approx(b, rel=0.2)
    assert reading["hi"] >= b


def test_rate_random_walk_with_arw_and_quantisation_k_within_40_percent() -> None:
    rng = np.random.default_rng(105)
    rate, hours = 20.0, 10.0
    n = int(hours * 3600 * rate)
    ts = 1.0 / rate
    n_arw = units.from_display("arw", 0.01)  # 0.01 °/√h
    k_rrw = units.from_display("rrw", 0.5)  # 0.5 °/h/√h
    lsb = 1e-6  # rad (angle output quantisation)
    rate_true = rng.normal(0.0, n_arw / math.sqrt(ts), n) + np.cumsum(rng.normal(0.0, k_rrw * math.sqrt(ts), n))
    angle = np.concatenate([[0.0], np.cumsum(rate_true) * ts])
    y = np.diff(np.round(angle / lsb) * lsb) * rate
    _, fit = _fit(y, rate)
    assert fit.terms["K"][0] == pytest.approx(k_rrw, rel=0.4)
    assert fit.terms["N"][0] == pytest.approx(n_arw, rel=0.1)
    assert to_display("K", fit.terms["K"][0], "rad/s")[1] == "deg/h/√h"


def test_unweighted_least_squares_would_go_negative_but_the_fit_does_not() -> None:
    """The reason for NNLS with weights (spec): plain least squares on white noise returns negative C_n."""
    rng = np.random.default_rng(106)
    rate = 100.0
    y = rng.normal(0.0, 1e-3, 2**18)
    res, fit = _fit(y, rate)
    a = np.stack([res.tau**p for p in (-2, -1, 0, 1, 2)], axis=1)
    c_ls = np.linalg.lstsq(a, res.var["oavar"][:, 0], rcond=None)[0]
    assert np.any(c_ls < 0)
    assert np.all(fit.coefficients >= 0)


def test_analyse_noise_json_structure_units_and_display() -> None:
    rng = np.random.default_rng(107)
    n, rate = 50_000, 100.0
    chans = {"gyro_x": rng.normal(0, 1e-4, n), "accel_x": rng.normal(9.8, 1e-3, n)}
    out = analyse_noise(chans, rate, {"gyro_x": "rad/s", "accel_x": "m/s^2"})
    g = out["channels"]["gyro_x"]
    for key in ("tau", "adev", "oadev", "totdev", "mdev"):
        assert len(g[key]) == len(g["tau"]) > 5
    assert set(g["terms"]) == {"Q", "N", "B", "K", "R"}
    assert g["terms"]["N"]["unit"] == "rad/s^0.5"
    assert out["channels"]["accel_x"]["terms"]["B"]["unit"] == "m/s^2"
    assert g["terms_display"]["N"]["unit"] == "deg/√h"
    assert out["channels"]["accel_x"]["terms_display"]["N"]["unit"] == "µg/√Hz"
    assert g["terms"]["N"]["value"] == pytest.approx(1e-4 / 10, rel=0.05)
    assert g["terms_display"]["N"]["value"] == pytest.approx(g["terms"]["N"]["value"] / units.DEG_PER_SQRT_HOUR)
    with pytest.raises(ValueError, match="differ in length"):
        analyse_noise({"a": np.zeros(100), "b": np.zeros(99)}, 1.0)


def test_quoted_sigmas_match_the_scatter_over_repeated_records() -> None:
    """N (white) and B (flicker): the quoted 1σ is within a factor 2 of the scatter over 24 seeded records."""
    rate, n, sw, b = 100.0, 2**16, 1e-3, 2e-5
    vals, sigs = {"N": [], "B": []}, {"N": [], "B": []}
    for seed in range(24):
        rng = np.random.default_rng(1000 + seed)
        y = rng.normal(0.0, sw, n) + pink(n, rate, b, rng)
        _, fit = _fit(y, rate)
        for t in vals:
            vals[t].append(fit.terms[t][0])
            sigs[t].append(fit.terms[t][1])
    for t in vals:
        ratio = np.median(sigs[t]) / np.std(vals[t])
        assert 0.5 < ratio < 2.0, (t, ratio)


@pytest.mark.parametrize("estimator", FIT_ESTIMATORS)
def test_every_fit_estimator_recovers_white_and_random_walk_terms(estimator: str) -> None:
    """White FM + rate random walk (N, K) through each accepted estimator's own gains (Allan or Hadamard model):
    N within 5 %, K within 40 % (one 4·10⁴-sample record); the Hadamard model reports no rate ramp."""
    rng = np.random.default_rng(107)
    rate, n = 10.0, 40_000
    n_arw, k_rrw = 1e-3, 2e-5
    ts = 1.0 / rate
    y = rng.normal(0.0, n_arw / math.sqrt(ts), n) + np.cumsum(rng.normal(0.0, k_rrw * math.sqrt(ts), n))
    out = analyse_noise({"g": y}, rate, "rad/s", estimators=(estimator,), fit_estimator=estimator)
    ch = out["channels"]["g"]
    assert ch["terms"]["N"]["value"] == pytest.approx(n_arw, rel=0.05)
    assert ch["terms"]["K"]["value"] == pytest.approx(k_rrw, rel=0.4)
    hadamard = estimator in ("hdev", "ohdev", "htotdev")
    assert ch["fit"]["model"] == ("hadamard" if hadamard else "allan")
    assert math.isnan(ch["terms"]["R"]["value"]) == hadamard


def test_fit_refuses_estimators_without_a_term_model() -> None:
    for name in ("mdev", "mtotdev", "theo1", "mtie"):
        with pytest.raises(ValueError, match="fixed gain per noise term"):
            analyse_noise({"g": np.ones(100)}, 1.0, fit_estimator=name)

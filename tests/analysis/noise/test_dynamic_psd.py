"""Dynamic Allan deviation (analysis/noise/dynamic.py) against allantools per window; the PSD (analysis/noise/
psd.py) against allantools' Welch PSD, its noise terms against the Allan terms and the truth on simulated records."""

from __future__ import annotations

import math

import allantools
import numpy as np
import pytest

from analysis.noise.dynamic import dynamic_adev
from analysis.noise.psd import rate_psd, term_psd
from analysis.noise.terms import analyse_noise
from tests.noise_synth import pink


def test_dynamic_adev_equals_allantools_per_window_and_sees_a_noise_burst() -> None:
    rng = np.random.default_rng(1)
    rate = 10.0
    y = rng.normal(size=6000)
    y[3000:4000] *= 5.0  # a burst in the middle of the record
    d = dynamic_adev(y, rate, 100.0, 50.0)
    assert d["adev"].shape == (d["t_start"].size, d["tau"].size)
    for i, t0 in enumerate(d["t_start"]):
        seg = y[int(t0 * rate) : int(t0 * rate) + 1000]
        tau, dev, _, _ = allantools.oadev(seg, rate, "freq", d["tau"])
        np.testing.assert_allclose(d["adev"][i, np.isin(d["tau"], tau)], dev, rtol=1e-9)
    burst = (d["t_start"] >= 300.0) & (d["t_start"] + 100.0 <= 400.0)
    quiet = d["t_start"] + 100.0 <= 300.0
    assert d["adev"][burst, 0].min() > 3.0 * d["adev"][quiet, 0].max()


@pytest.mark.parametrize("n", [10_000, 8_192])
def test_welch_psd_equals_allantools_scipy_psd(n: int) -> None:
    """allantools.noise.scipy_psd (Welch, Hann, 50 % overlap, segments of N/4) = ``rate_psd(..., segments=7)``
    (segments of 2N/(7 + 1)): the same ordinates (the zero-frequency one dropped) to 1e-9."""
    from allantools import noise

    y = np.random.default_rng(n).normal(0.0, 1e-3, n) + 1e-7 * np.arange(n) + 0.2
    f_ref, p_ref = noise.scipy_psd(y, 20.0, 4)
    ours = rate_psd(y, 20.0, segments=7)
    np.testing.assert_allclose(ours["f"], f_ref[1:], rtol=1e-12)
    np.testing.assert_allclose(ours["psd"], p_ref[1:], rtol=1e-9)


def test_dynamic_adev_refuses_a_window_longer_than_the_record() -> None:
    with pytest.raises(ValueError, match="longer than the record"):
        dynamic_adev(np.zeros(100), 10.0, 20.0)


def _records(rng: np.random.Generator, n: int, rate: float) -> dict[str, tuple[np.ndarray, str, float]]:
    return {
        "white": (rng.normal(size=n) * 1e-3, "N", 1e-3 / math.sqrt(rate)),
        "flicker": (pink(n, rate, 1e-4, rng), "B", 1e-4),
        "random_walk": (np.cumsum(rng.normal(size=n)) * 1e-5, "K", 1e-5 * math.sqrt(rate)),
    }


@pytest.mark.parametrize("kind", ["white", "flicker", "random_walk"])
def test_psd_terms_agree_with_the_allan_terms_and_the_truth(kind: str) -> None:
    """Measured on these records: |PSD − Allan| = 1.4, 2.0, 2.1 combined standard uncertainties (white, flicker,
    random walk); asserted within the expanded uncertainty at k = 3, and each within 3 % of the true term."""
    rate, n = 10.0, 2**18
    y, term, true = _records(np.random.default_rng(1), n, rate)[kind]
    p = rate_psd(y, rate)
    allan = analyse_noise({"y": y}, rate)["channels"]["y"]["terms"][term]
    v, s = p["terms"][term]
    assert abs(v - allan["value"]) <= 3.0 * math.hypot(s, allan["sigma"])
    assert v == pytest.approx(true, rel=0.03)


def test_term_psd_is_twice_the_ieee_two_sided_form() -> None:
    f = np.array([0.1, 1.0])
    s = term_psd(f, {"N": 2.0, "B": 1.0, "K": 3.0}, 0.01)
    np.testing.assert_allclose(s["N"], 8.0)
    np.testing.assert_allclose(s["B"], 2.0 / (2 * np.pi * f))
    np.testing.assert_allclose(s["K"], 18.0 / (2 * np.pi * f) ** 2)

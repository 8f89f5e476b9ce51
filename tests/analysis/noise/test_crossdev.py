"""PDEV, GCODEV and the three-cornered hat (analysis/noise/crossdev.py) against allantools."""

from __future__ import annotations

import allantools
import numpy as np
import pytest

from analysis.noise.crossdev import gcodev, pdev, three_cornered_hat

RATE = 10.0


@pytest.mark.parametrize("data_type", ["freq", "phase"])
def test_pdev_equals_allantools(data_type: str) -> None:
    rng = np.random.default_rng(1)
    y = rng.normal(size=3000) + 0.02 * np.cumsum(rng.normal(size=3000))
    tau, dev, n = pdev(y, RATE, "octave", data_type)
    t_ref, d_ref, _, n_ref = allantools.pdev(y, RATE, data_type, tau)
    np.testing.assert_allclose(tau, t_ref, rtol=1e-12)
    np.testing.assert_allclose(dev, d_ref, rtol=1e-9)
    np.testing.assert_array_equal(n, n_ref)


def test_pdev_long_tau_uses_the_fft_convolution() -> None:
    y = np.random.default_rng(2).normal(size=2000)
    tau, dev, _ = pdev(y, RATE, np.array([12.8, 30.0, 99.8]), "freq")  # m = 128, 300, 998 (2 terms)
    _, d_ref, _, _ = allantools.pdev(y, RATE, "freq", tau)
    np.testing.assert_allclose(dev, d_ref, rtol=1e-9)


def test_gcodev_equals_allantools_in_magnitude_and_keeps_the_sign() -> None:
    rng = np.random.default_rng(3)
    common = np.cumsum(rng.normal(size=4000)) * 0.05
    y1 = common + rng.normal(size=4000)
    y2 = common + rng.normal(size=4000)
    tau, dev, n = gcodev(y1, y2, RATE)
    t_ref, d_ref, _, n_ref = allantools.gcodev(y1, y2, RATE, "freq", tau)
    np.testing.assert_allclose(np.abs(dev), d_ref, rtol=1e-9)
    np.testing.assert_array_equal(n, n_ref)
    assert dev[-1] > 0  # the common random walk dominates long τ
    _, anti, _ = gcodev(y1, -y1, RATE)
    assert np.all(anti < 0)


def test_three_cornered_hat_equals_allantools_and_separates_the_units() -> None:
    rng = np.random.default_rng(4)
    n = 50_000
    table = np.cumsum(rng.normal(size=n)) * 0.1  # the common input, removed by the pair differences
    sig = {"a": 1.0, "b": 2.0, "c": 0.5}
    units = {k: table + s * rng.normal(size=n) for k, s in sig.items()}
    res = three_cornered_hat(units["a"], units["b"], units["c"], RATE)
    tau = res["tau"]
    ab, bc, ca = units["a"] - units["b"], units["b"] - units["c"], units["c"] - units["a"]
    x = [allantools.frequency2phase(d, RATE) for d in (ab, bc, ca)]
    _, dev_a, _, _ = allantools.three_cornered_hat_phase(x[0], x[1], x[2], RATE, tau, allantools.oadev)
    np.testing.assert_allclose(res["classic"]["a"], dev_a, rtol=1e-9)
    short = tau < 1.0  # many averages: each unit's white noise N = σ/√rate is recovered
    for k, s in sig.items():
        want = s / np.sqrt(RATE * tau[short])
        np.testing.assert_allclose(res["gcodev"][k][short], want, rtol=0.1)
        np.testing.assert_allclose(res["classic"][k][short], want, rtol=0.1)

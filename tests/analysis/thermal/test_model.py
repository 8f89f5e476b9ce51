"""The thermal parameter model: GLS against numpy's weighted polyfit, order selection and coverage on
synthetic plateau estimates with correlated covariances, the dT/dt term, the residual and the hysteresis."""

from __future__ import annotations

import numpy as np
import pytest

from analysis.thermal.model import PlateauEstimate, compensation_residual, fit_thermal_model, hysteresis

TEMPS = 273.15 + np.array([-20.0, 0.0, 20.0, 40.0, 60.0])
REF = 273.15 + 20.0


def synth(rng, coeffs, sigma, temps=TEMPS, rates=None, corr=0.5):
    """Plateau estimates of P parameters p(T) = Σ c_k (T − REF)^k (+ c_rate·Ṫ), correlated noise."""
    p = len(coeffs)
    c = np.full((p, p), corr) + (1 - corr) * np.eye(p)
    cov = c * np.outer(sigma, sigma)
    lo = np.linalg.cholesky(cov)
    out = []
    for i, t in enumerate(temps):
        r = 0.0 if rates is None else rates[i]
        truth = np.array([np.polyval(cf[0][::-1], t - REF) + cf[1] * r for cf in coeffs])
        out.append(PlateauEstimate(float(t), truth + lo @ rng.standard_normal(p), cov, rate=r))
    return out


def test_fixed_order_matches_numpy_weighted_polyfit():
    rng = np.random.default_rng(1)
    pls = synth(rng, [((1e-3, 2e-5, 3e-7), 0.0)], np.array([1e-5]))
    m = fit_thermal_model(pls, ["b"], reference=REF, orders=[2])
    t = np.array([p.temperature for p in pls]) - REF
    y = np.array([p.x[0] for p in pls])
    ref, cov = np.polyfit(t, y, 2, w=np.full(5, 1e5), cov="unscaled")
    c, ccov = m.parameter("b")
    np.testing.assert_allclose(c, ref[::-1], rtol=1e-9)
    np.testing.assert_allclose(np.diag(ccov), np.diag(cov)[::-1], rtol=1e-8)


def test_orders_are_picked_and_coefficients_covered():
    # the size of the real problem: 30 parameters (18 accelerometer + 12 gyro) at 5 plateaus, orders 0, 1, 2
    rng = np.random.default_rng(7)
    kinds = [((3.0,), 0.0), ((1.0, 0.4), 0.0), ((0.5, -0.3, 0.01), 0.0)]
    truth = [kinds[i % 3] for i in range(30)]
    true_orders = np.array([i % 3 for i in range(30)])
    names = [f"p{i}" for i in range(30)]
    hits = np.zeros(30)
    inside, total = 0, 0
    runs = 40
    for _ in range(runs):
        m = fit_thermal_model(synth(rng, truth, np.ones(30), corr=0.3), names, reference=REF)
        ok = np.array(m.orders) == true_orders
        hits += ok
        for p in np.flatnonzero(ok):
            c, cov = m.parameter(names[p])
            err = np.abs(c - np.asarray(truth[p][0])) / np.sqrt(np.diag(cov))
            inside += int(np.sum(err <= 2.0))
            total += err.size
    for order in range(3):
        assert hits[true_orders == order].mean() / runs >= 0.9, (order, hits / runs)
    assert 0.91 <= inside / total <= 0.98, inside / total


def test_rate_term_is_recovered_from_heating_and_cooling_points():
    rng = np.random.default_rng(3)
    temps = 273.15 + np.array([-20.0, 0.0, 20.0, 40.0, 60.0, 50.0, 30.0, 10.0, -10.0])
    rates = np.array([0.0, 0.01, 0.01, 0.01, 0.0, -0.01, -0.01, -0.01, -0.01])
    pls = synth(rng, [((1.0, 0.05), 30.0)], np.array([0.01]), temps=temps, rates=rates)
    m = fit_thermal_model(pls, ["b"], reference=REF, orders=[1], rate_term=True)
    c, cov = m.parameter("b")
    assert abs(c[2] - 30.0) < 3 * np.sqrt(cov[2, 2])
    assert np.sqrt(cov[2, 2]) < 1.0


def test_residual_after_compensation_and_hysteresis():
    rng = np.random.default_rng(5)
    heat = synth(rng, [((1.0, 0.05), 0.0)], np.array([0.01]))
    cool = synth(rng, [((1.2, 0.05), 0.0)], np.array([0.01]))
    mh = fit_thermal_model(heat, ["b"], reference=REF, orders=[1])
    mc = fit_thermal_model(cool, ["b"], reference=REF, orders=[1])
    res = compensation_residual(mh, heat)
    assert all(abs(r["residual"][0]) <= 3 * r["u"][0] + 1e-12 for r in res)
    d, u = hysteresis(mh, mc, [REF])
    assert d[0, 0] == pytest.approx(-0.2, abs=3 * u[0, 0])
    with pytest.raises(ValueError):
        hysteresis(mh, mc, [REF + 100.0])


def test_a_common_offset_shifts_only_the_constant_coefficients_and_adds_its_covariance():
    from analysis.thermal.model import with_common_offset

    rng = np.random.default_rng(4)
    pls = synth(rng, [((1e-3, 2e-5), 0.0), ((5e-5, 1e-6, 2e-8), 0.0)], np.array([1e-5, 2e-6]))
    m = fit_thermal_model(pls, ["a", "s"], reference=REF, orders=[1, 2])
    delta = 3e-6  # the same shift of "s" at every plateau (a reference common to the run)
    shifted = [PlateauEstimate(p.temperature, p.x + np.array([0.0, delta]), p.covariance) for p in pls]
    m2 = fit_thermal_model(shifted, ["a", "s"], reference=REF, orders=[1, 2])
    diff = m2.coefficients - m.coefficients
    s0 = m.slices()[1].start
    np.testing.assert_allclose(diff[s0], delta, rtol=1e-9)  # c_0 of "s" moves by exactly δ ...
    np.testing.assert_allclose(np.delete(diff, s0), 0.0, atol=1e-12 * abs(delta) + 1e-20)  # ... nothing else
    u2 = 4e-12
    m3 = with_common_offset(m, ["s"], [[u2]])
    added = m3.covariance - m.covariance
    assert added[s0, s0] == pytest.approx(u2) and np.count_nonzero(added) == 1
    _, u_before = m.evaluate([REF + 30.0])
    _, u_after = m3.evaluate([REF + 30.0])
    assert u_after[0, 1] == pytest.approx(np.hypot(u_before[0, 1], 2e-6)) and u_after[0, 0] == u_before[0, 0]

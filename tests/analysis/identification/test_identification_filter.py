"""Streaming Kalman identifier and batch least squares on synthetic ten-step / 24-position data."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.stats
from filterpy.kalman import KalmanFilter

from analysis.identification import batch as bi
from analysis.identification import model as am
from analysis.identification import plan as ip
from analysis.identification.kalman import StreamingIdentifier, estimate_measurement_noise
from analysis.units import ARCSEC, DEG, MM
from tests.identification_synth import P0, PRIOR_SIGMA, TRUTH, G, noise_sd, simulate

RATE = 100.0
SD = noise_sd(15.0, RATE)
R = np.full(3, SD**2)


def _run(steps, outputs, p0=P0, **kw) -> StreamingIdentifier:
    kf = StreamingIdentifier(R, p0, sample_rate=RATE, **kw)
    for st, fo in zip(steps, outputs, strict=True):
        kf.update(fo, st.f_ref, st.omega, st.label)
    return kf


def _stack(steps, outputs):
    return (
        np.concatenate(outputs),
        np.concatenate([s.f_ref for s in steps]),
        np.concatenate([s.omega for s in steps]),
    )


@pytest.fixture(scope="module")
def ten_step_slow():
    steps = ip.ten_step_sequence(G, RATE, hold_s=60.0, spin_rate=1.6 * DEG)
    outputs = simulate(steps, TRUTH, SD, np.random.default_rng(2026))
    return steps, outputs


def test_kf_equals_batch_least_squares(ten_step_slow) -> None:
    steps, outputs = ten_step_slow
    kf = _run(steps, outputs)
    fo, fr, om = _stack(steps, outputs)
    for method in ("qr", "normal"):
        b = bi.batch_identify(fo, fr, om, R, None, P0, method=method)
        scale = np.abs(b.x) + b.sigma
        assert np.max(np.abs(kf.estimate - b.x) / scale) < 1e-9
        np.testing.assert_allclose(kf.sigma, b.sigma, rtol=1e-9)
        np.testing.assert_allclose(kf.covariance, b.covariance, rtol=0, atol=1e-9 * np.outer(b.sigma, b.sigma).max())
    assert kf.rank_and_condition()[0] == 18
    assert len(kf.history) == len(steps) and kf.history[-1].step == "C spin+"
    np.testing.assert_allclose(kf.history[-1].x, kf.estimate)
    assert kf.history[-1].time == pytest.approx(fo.shape[0] / RATE)


def test_block_update_equals_per_sample_filterpy_updates() -> None:
    """One information block == ordinary per-sample 3-D filterpy updates (independent reference)."""
    steps = ip.ten_step_sequence(G, 2.0, hold_s=5.0, spin_rate=20 * DEG)
    rng = np.random.default_rng(9)
    outputs = simulate(steps, TRUTH, SD, rng)
    kf = _run(steps, outputs)
    s = PRIOR_SIGMA
    ref = KalmanFilter(dim_x=18, dim_z=3)
    ref.x = np.zeros((18, 1))
    ref.P = np.eye(18)
    for st, fo in zip(steps, outputs, strict=True):
        h = am.design_matrix(st.f_ref, st.omega) * s
        for n in range(fo.shape[0]):
            ref.update((fo[n] - st.f_ref[n]).reshape(3, 1), R=np.diag(R), H=h[n])
    x_ref = ref.x.ravel() * s
    sig_ref = np.sqrt(np.diag(ref.P)) * s
    assert np.max(np.abs(kf.estimate - x_ref) / (np.abs(x_ref) + sig_ref)) < 1e-9
    np.testing.assert_allclose(kf.sigma, sig_ref, rtol=1e-8)


def test_every_parameter_within_3_sigma_and_residuals(ten_step_slow) -> None:
    steps, outputs = ten_step_slow
    kf = _run(steps, outputs)
    err = (kf.estimate - TRUTH) / kf.sigma
    assert np.all(np.abs(err) < 3.0), dict(zip(am.PARAM_NAMES, np.round(err, 2), strict=True))
    # Well-determined parameters are far better than their prior; r at 1.6 °/s is not (planner's point).
    assert np.all(kf.sigma[:15] < 0.01 * PRIOR_SIGMA[:15])
    assert np.all(kf.sigma[15:] > 5 * MM)
    stats = kf.residual_statistics()
    assert set(stats) == {s.label for s in steps}
    for st, fo in zip(steps, outputs, strict=True):
        e = fo - st.f_ref - np.einsum("nij,j->ni", am.design_matrix(st.f_ref, st.omega), kf.estimate)
        np.testing.assert_allclose(stats[st.label].rms, np.sqrt((e**2).mean(axis=0)), rtol=1e-9)
        np.testing.assert_allclose(stats[st.label].mean, e.mean(axis=0), rtol=1e-6, atol=1e-12)
        assert stats[st.label].count == fo.shape[0]
    all_rms = np.array([s.rms for s in stats.values()])
    assert np.all(np.abs(all_rms / SD - 1.0) < 0.05)


def test_information_rank_single_position_24_static_and_ten_step() -> None:
    one = ip.cube24_sequence(G, RATE, hold_s=10.0)[:1]
    cube = ip.cube24_sequence(G, RATE, hold_s=1.0, compress=True)
    results = {}
    for name, steps in {
        "one": one,
        "cube24": cube,
        "ten_slow": ip.ten_step_sequence(G, RATE, spin_rate=1.6 * DEG, points_per_rev=360),
        "ten_fast": ip.ten_step_sequence(G, RATE, spin_rate=30 * DEG, points_per_rev=360),
        "ten_holds_only": [s for s in ip.ten_step_sequence(G, RATE, points_per_rev=360) if "spin" not in s.label],
    }.items():
        info = np.zeros((18, 18))
        for st in steps:
            info += am.information_from_gram(am.regressor_gram(st.f_ref, st.omega, weights=st.weights), R)[0]
        results[name] = bi.information_rank(info, R)
    assert results["one"][0] == 3
    assert results["cube24"][0] == 15
    assert results["ten_holds_only"][0] == 15
    assert results["ten_slow"][0] == 18 and results["ten_fast"][0] == 18
    assert np.isinf(results["cube24"][1]) and np.isfinite(results["ten_fast"][1])
    assert results["ten_fast"][1] < results["ten_slow"][1]
    # 1 arcsec attitude jitter at a single position must not create information (tolerance argument).
    rng = np.random.default_rng(4)
    ang = np.tile(ip.GROUPS["A"][0], (6000, 1)) + rng.normal(0.0, 1.0 * ARCSEC, (6000, 3))
    from analysis import gimbal

    f = gimbal.gravity_in_body(ang, G)
    info = am.information_from_gram(am.regressor_gram(f, np.zeros_like(f)), R)[0]
    assert bi.information_rank(info, R)[0] == 3
    # The unobservable parameters of the static set are exactly the size-effect terms.
    info = np.zeros((18, 18))
    for st in cube:
        info += am.information_from_gram(am.regressor_gram(st.f_ref, st.omega, weights=st.weights), R)[0]
    assert bi.unobservable_parameters(info, R) == ("r_x", "r_y", "r_z")


def test_batch_without_prior() -> None:
    steps = ip.ten_step_sequence(G, RATE, hold_s=20.0, spin_rate=30 * DEG, revolutions=2)
    outputs = simulate(steps, TRUTH, SD, np.random.default_rng(21))
    fo, fr, om = _stack(steps, outputs)
    b = bi.batch_identify(fo, fr, om, R)
    assert not b.used_prior and b.rank == 18
    assert np.all(np.abs(b.x - TRUTH) < 3.5 * b.sigma)
    bn = bi.batch_identify(fo, fr, om, R, method="normal")
    assert np.max(np.abs(bn.x - b.x) / (np.abs(b.x) + b.sigma)) < 1e-9
    np.testing.assert_allclose(b.residual_rms, SD, rtol=0.05)
    # 24 static positions without a prior: rank 15, a clear error naming r.
    cube = ip.cube24_sequence(G, RATE, hold_s=5.0)
    outs = simulate(cube, TRUTH, SD, np.random.default_rng(1))
    fo, fr, om = _stack(cube, outs)
    with pytest.raises(ValueError, match=r"rank 15 < 18: r_x, r_y, r_z"):
        bi.batch_identify(fo, fr, om, R)
    b24 = bi.batch_identify(fo, fr, om, R, None, P0)
    assert b24.rank == 15
    np.testing.assert_allclose(b24.sigma[15:], PRIOR_SIGMA[15:], rtol=1e-9)  # r stays at its prior


def test_measurement_noise_estimate() -> None:
    rng = np.random.default_rng(8)
    n = 20000
    sd = np.array([1e-3, 2e-3, 0.5e-3])
    drift = np.linspace(0.0, 5e-3, n)[:, None]
    f = np.array([0.0, 0.0, G]) + drift + rng.normal(0.0, 1.0, (n, 3)) * sd
    for method in ("detrend", "difference"):
        np.testing.assert_allclose(estimate_measurement_noise(f, method), sd**2, rtol=0.05)
    with pytest.raises(ValueError, match="too short"):
        estimate_measurement_noise(f[:5])


def test_bad_input_and_process_noise() -> None:
    with pytest.raises(ValueError, match="positive"):
        StreamingIdentifier(R, np.zeros((18, 18)))
    kf = StreamingIdentifier(R, P0, q=1e-6, sample_rate=RATE)
    with pytest.raises(ValueError, match="step 'A': f_out, f_ref and omega"):
        kf.update(np.zeros((4, 3)), np.zeros((5, 3)), np.zeros((4, 3)), "A")
    with pytest.raises(ValueError, match="non-finite"):
        kf.update(np.full((4, 3), np.nan), np.zeros((4, 3)), np.zeros((4, 3)), "A")
    steps = ip.ten_step_sequence(G, 10.0, hold_s=10.0, spin_rate=30 * DEG)
    outputs = simulate(steps, TRUTH, noise_sd(15.0, 10.0), np.random.default_rng(3))
    for st, fo in zip(steps, outputs, strict=True):
        kf.update(fo, st.f_ref, st.omega, st.label)
    q0 = _run(steps, outputs)
    assert np.all(kf.sigma >= q0.sigma * (1 - 1e-12)) and np.any(kf.sigma > q0.sigma * 1.001)


def test_update_with_each_triads_output_equals_the_output_side_by_side() -> None:
    """The unit's accelerometer and gyro outputs given as they were read (a tuple, not copied into one array):
    the same estimate and covariance, bit for bit, as the (n, 6) output; wrong shapes and non-finite samples in
    either array are refused as for one array."""
    from analysis.identification.gyro import GyroModel
    from analysis.identification.specification import UnitModel

    unit = UnitModel((am.ACCELEROMETER, GyroModel()))
    r_var = np.array([1e-6] * 3 + [1e-9] * 3)
    p0 = np.eye(unit.n_params) * 1e-4
    rng = np.random.default_rng(8)
    one, two = (StreamingIdentifier(r_var, p0, model=unit, sample_rate=RATE) for _ in range(2))
    for k in range(4):
        n = 500 + 100 * k
        f, om, earth = rng.normal(0, 6, (n, 3)), rng.normal(0, 0.5, (n, 3)), rng.normal(0, 5e-5, (n, 3))
        y = unit.ideal(f, om, earth) + rng.normal(0, 1e-3, (n, 6))
        one.update(y, f, om, f"s{k}", earth=earth)
        two.update((y[:, :3].copy(), y[:, 3:].copy()), f, om, f"s{k}", earth=earth)
    assert np.array_equal(one.estimate, two.estimate) and np.array_equal(one.covariance, two.covariance)
    with pytest.raises(ValueError, match="f_out, f_ref and omega"):
        two.update((y[:, :3].copy(), y[:-1, 3:].copy()), f, om, "x", earth=earth)
    with pytest.raises(ValueError, match="f_out, f_ref and omega"):
        two.update((y[:, :3].copy(),), f, om, "x", earth=earth)
    bad = y[:, 3:].copy()
    bad[7, 1] = np.inf
    with pytest.raises(ValueError, match="non-finite"):
        two.update((y[:, :3].copy(), bad), f, om, "x", earth=earth)


@pytest.mark.slow
def test_monte_carlo_cramer_rao_full_sequence() -> None:
    """Full ten-step sequence at 100 Hz, 200 seeds: achieved RMS error ≤ 1.2× the filter's (Cramér–Rao) σ."""
    steps = ip.ten_step_sequence(G, RATE, hold_s=60.0, spin_rate=30 * DEG, revolutions=2)
    n_runs = 200
    errs = np.empty((n_runs, 18))
    sig = np.zeros(18)
    for k in range(n_runs):
        kf = _run(steps, simulate(steps, TRUTH, SD, np.random.default_rng(1000 + k)))
        errs[k] = kf.estimate - TRUTH
        sig = kf.sigma
    rms = np.sqrt((errs**2).mean(axis=0))
    assert np.all(rms <= 1.2 * sig), dict(zip(am.PARAM_NAMES, np.round(rms / sig, 2), strict=True))
    assert np.max(np.abs(errs.mean(axis=0) / sig)) < 4.0 / np.sqrt(n_runs)


@pytest.mark.slow
def test_monte_carlo_nees_is_chi2_18() -> None:
    """NEES over 1000 seeds is χ²₁₈ (mean in its 99 % band, KS test).

    The estimator is linear and exact, so NEES consistency does not depend on the record length; the ten-step
    geometry is kept and the rate/holds reduced (20 Hz, 10 s) to afford 1000 seeds (σ of the mean NEES 0.19).
    """
    rate = 20.0
    sd = noise_sd(15.0, rate)
    r_var = np.full(3, sd**2)
    steps = ip.ten_step_sequence(G, rate, hold_s=10.0, spin_rate=30 * DEG)
    n_runs = 1000
    nees = np.empty(n_runs)
    for k in range(n_runs):
        outputs = simulate(steps, TRUTH, sd, np.random.default_rng(1000 + k))
        kf = StreamingIdentifier(r_var, P0)
        for st, fo in zip(steps, outputs, strict=True):
            kf.update(fo, st.f_ref, st.omega, st.label)
        nees[k] = kf.nees(TRUTH)
    lo, hi = scipy.stats.chi2.ppf([0.005, 0.995], 18 * n_runs) / n_runs
    assert lo < nees.mean() < hi, nees.mean()
    assert scipy.stats.kstest(nees, "chi2", args=(18,)).pvalue > 0.001

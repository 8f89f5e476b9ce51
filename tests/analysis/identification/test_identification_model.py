"""Accelerometer model: H derived from the model, lever-arm sign, inverse model, sufficient statistics."""

from __future__ import annotations

import numpy as np
import pytest

from analysis.identification import model as am
from analysis.units import DEG, MM, PPM, UG
from tests.identification_synth import TRUTH


def _random_samples(rng: np.random.Generator, n: int) -> tuple[np.ndarray, np.ndarray]:
    f = rng.normal(0.0, 6.0, (n, 3))
    w = rng.normal(0.0, 0.5, (n, 3))
    return f, w


def test_names_kinds_and_display_units() -> None:
    assert len(am.PARAM_NAMES) == 18 == len(am.PARAM_KINDS)
    assert am.PARAM_NAMES[6:12] == ("tau_xy", "tau_xz", "tau_yx", "tau_yz", "tau_zx", "tau_zy")
    assert am.display_units()[:4] == ("µg", "µg", "µg", "ppm")
    disp = am.to_display(TRUTH)
    np.testing.assert_allclose(disp[[0, 3, 6, 12, 15]], [100.0, 200.0, 30.0, 20.0, -30.0], rtol=1e-12)
    np.testing.assert_allclose(am.from_display(disp), TRUTH, rtol=1e-15)
    with pytest.raises(ValueError, match="no value given for r_x"):
        am.sigma_from_display({"bias": 1, "scale": 1, "misalignment": 1, "quadratic": 1})


def test_centripetal_regressor() -> None:
    c = am.centripetal([[1.0, 2.0, 3.0]])
    np.testing.assert_allclose(c, [[13.0, 10.0, 5.0]])


def test_misalignment_convention_tau_ij_couples_f_j_into_axis_i() -> None:
    x = np.zeros(18)
    x[am.PARAM_NAMES.index("tau_xy")] = 1e-3
    out = am.predict(x, [[0.0, 9.8, 0.0]], [[0.0, 0.0, 0.0]])
    np.testing.assert_allclose(out, [[9.8e-3, 9.8, 0.0]], atol=1e-15)
    m, *_ = am.error_matrices(x)
    assert m[0, 1] == 1e-3 and m[1, 0] == 0.0


def test_design_matrix_is_exactly_the_linearised_model() -> None:
    """z = f_out − f is linear in x; H from design_matrix must reproduce predict for arbitrary x."""
    rng = np.random.default_rng(3)
    f, w = _random_samples(rng, 200)
    h = am.design_matrix(f, w)
    for _ in range(5):
        x = rng.normal(0.0, 1e-3, 18)
        np.testing.assert_allclose(np.einsum("nij,j->ni", h, x), am.predict(x, f, w) - f, rtol=0, atol=1e-14)
    # Column k is the response to a unit parameter k (finite-difference independent check).
    for k in range(18):
        e = np.zeros(18)
        e[k] = 1.0
        np.testing.assert_allclose(h[:, :, k], am.predict(e, f, w) - f, atol=1e-12)


def test_size_effect_sign_against_lever_arm_physics() -> None:
    """Full lever-arm physics [ω×(ω×ρ_i)]_i for a spin about an axis j equals +r_i c_i with r_i = −ρ_{i,i}."""
    rng = np.random.default_rng(5)
    rho = rng.normal(0.0, 0.03, (3, 3))  # row i: position of accelerometer i, body frame, m
    x = np.zeros(18)
    x[15:18] = -np.diag(rho)
    for j in range(3):
        for rate in (1.6 * DEG, -30 * DEG, 100 * DEG):
            w = np.zeros(3)
            w[j] = rate
            physics = np.array([np.cross(w, np.cross(w, rho[i]))[i] for i in range(3)])
            model = am.predict(x, [[0.0, 0.0, 0.0]], [w])[0]
            np.testing.assert_allclose(model, physics, rtol=1e-12, atol=1e-18)
    # A 3 cm lever arm at 1.6 °/s is 2.4 µg (spec figure).
    assert abs(0.03 * (1.6 * DEG) ** 2 / UG - 2.39) < 0.01


def test_correct_inverts_predict_to_machine_precision() -> None:
    rng = np.random.default_rng(7)
    f, w = _random_samples(rng, 5000)
    for x in (TRUTH, TRUTH * 50.0):  # typical and 50× exaggerated errors (d f up to 1e-3)
        fo = am.predict(x, f, w)
        back = am.correct(x, fo, w, chunk=1024)
        np.testing.assert_allclose(back, f, rtol=0, atol=8 * np.finfo(float).eps * np.abs(f).max())
        np.testing.assert_allclose(am.predict(x, back, w), fo, rtol=0, atol=8 * np.finfo(float).eps * 30)
    # Without quadratic terms the inverse is the exact linear solve.
    x = TRUTH.copy()
    x[12:15] = 0.0
    np.testing.assert_allclose(am.correct(x, am.predict(x, f, w), w), f, atol=1e-13)


def test_correct_reports_non_invertible_model() -> None:
    x = np.zeros(18)
    x[12:15] = 1.0  # absurd: d f ~ 10
    with pytest.raises(ValueError, match="did not converge"):
        am.correct(x, [[-30.0, 5.0, 1.0]], [[0.0, 0.0, 0.0]])


def test_gram_information_equals_explicit_sums() -> None:
    rng = np.random.default_rng(11)
    f, w = _random_samples(rng, 3001)
    z = rng.normal(0.0, 1e-3, (3001, 3))
    wt = rng.uniform(0.5, 3.0, 3001)
    r = np.array([1e-6, 2e-6, 4e-6])
    info, eta = am.information_from_gram(am.regressor_gram(f, w, z, wt, chunk=256), r)
    h = am.design_matrix(f, w)
    hw = h / np.sqrt(r)[None, :, None] * np.sqrt(wt)[:, None, None]
    zw = z / np.sqrt(r) * np.sqrt(wt)[:, None]
    ref_info = np.einsum("nik,nil->kl", hw, hw)
    ref_eta = np.einsum("nik,ni->k", hw, zw)
    np.testing.assert_allclose(info, ref_info, rtol=1e-12, atol=1e-12 * np.abs(ref_info).max())
    np.testing.assert_allclose(eta, ref_eta, rtol=1e-12, atol=1e-12 * np.abs(ref_eta).max())
    # Residual moments from the Gram equal the directly computed residuals.
    x = rng.normal(0.0, 1e-4, 18)
    gram = am.regressor_gram(f, w, z)
    count, mean, rms = am.residual_moments(gram, x)
    e = z - np.einsum("nij,j->ni", h, x)
    assert count == 3001
    np.testing.assert_allclose(mean, e.mean(axis=0), rtol=1e-9)
    np.testing.assert_allclose(rms, np.sqrt((e**2).mean(axis=0)), rtol=1e-9)


def test_bad_shapes_are_reported() -> None:
    with pytest.raises(ValueError, match=r"shape \(n, 3\)"):
        am.design_matrix(np.zeros((4, 2)), np.zeros((4, 3)))
    with pytest.raises(ValueError, match="18 entries"):
        am.predict(np.zeros(17), np.zeros((1, 3)), np.zeros((1, 3)))
    with pytest.raises(ValueError, match="variance"):
        am.as_noise_variance([1.0, 0.0, 1.0])
    assert MM == 1e-3 and PPM == 1e-6


def test_mean_model_error_from_window_means_equals_the_mean_of_predict():
    """The registry's as found / as left use the window means only: the model is affine in f, f∘f and c(ω)."""
    from analysis.identification.model import centripetal, mean_model_error, predict

    rng = np.random.default_rng(11)
    x = rng.normal(size=18) * np.r_[[1e-3] * 3, [2e-4] * 3, [1e-4] * 6, [1e-5] * 3, [0.03] * 3]
    f = rng.normal(size=(500, 3)) * 9.8
    omega = rng.normal(size=(500, 3)) * 0.5
    expected = np.mean(predict(x, f, omega) - f, axis=0)
    got = mean_model_error(x, f.mean(axis=0), np.mean(f * f, axis=0), centripetal(omega).mean(axis=0))
    np.testing.assert_allclose(got, expected, rtol=1e-12, atol=1e-15)

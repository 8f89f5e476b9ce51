"""GUM budget (analysis.identification.budget): sensitivities against a re-solved estimator, components, mismatch."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from analysis.gimbal import body_rate, body_to_nav, gravity_in_body
from analysis.identification.budget import (
    StepGeometry,
    attitude_sensitivity,
    build_budget,
    data_information,
    gravity_sensitivity,
    mismatch_variance,
    step_offset_sensitivity,
)
from analysis.identification.model import design_matrix
from analysis.units import ARCSEC, MM, PPM, UG, UG_PER_G2

G = 9.80744
X_TRUE = np.array(
    [100 * UG, -80 * UG, 120 * UG, 200 * PPM, -150 * PPM, 250 * PPM]
    + [30 * ARCSEC, -25 * ARCSEC, 20 * ARCSEC, 35 * ARCSEC, -30 * ARCSEC, 15 * ARCSEC]
    + [20 * UG_PER_G2, -15 * UG_PER_G2, 10 * UG_PER_G2, -30 * MM, -28 * MM, -32 * MM]
)
PRIOR = np.array([1000 * UG] * 3 + [1000 * PPM] * 3 + [200 * ARCSEC] * 6 + [100 * UG_PER_G2] * 3 + [100 * MM] * 3)
NOISE_VAR = np.full(3, (15 * UG) ** 2 * 100.0)


def _model(x: np.ndarray, f: np.ndarray, w: np.ndarray) -> np.ndarray:
    """f_out written out term by term from the spec (independent of design_matrix)."""
    b, s, t, d, r = x[0:3], x[3:6], x[6:12], x[12:15], x[15:18]
    tmat = np.array([[0, t[0], t[1]], [t[2], 0, t[3]], [t[4], t[5], 0]])
    c = np.stack([w[:, 1] ** 2 + w[:, 2] ** 2, w[:, 2] ** 2 + w[:, 0] ** 2, w[:, 0] ** 2 + w[:, 1] ** 2], 1)
    return f + f * s + f @ tmat.T + b + d * f * f + r * c


def _ten_step_angles() -> list[tuple[str, str, np.ndarray, np.ndarray]]:
    """(name, kind, angles (m,3), rates (m,3)) of a ten-step-like sequence at 30 °/s."""
    r = math.radians
    out = []
    for grp, base, axis in (("A", (0, 0, 0), 2), ("B", (r(-90), r(-90), 0), 1), ("C", (r(90), 0, r(90)), 1)):
        for k in range(8):
            a = np.array(base, float)
            a[axis] += r(45 * k)
            out.append((f"{grp}/hold-{k}", "hold", a[None, :], np.zeros((1, 3))))
        phase = np.linspace(0, 2 * np.pi, 180, endpoint=False)
        a = np.tile(np.array(base, float), (180, 1))
        a[:, axis] += phase
        rates = np.zeros((180, 3))
        rates[:, axis] = r(30)
        out.append((f"{grp}/spin", "spin", a, rates))
    return out


def _geometry(g: float = G, dang: dict[str, np.ndarray] | None = None) -> list[StepGeometry]:
    geo = []
    for name, kind, ang, rat in _ten_step_angles():
        a = ang + (dang or {}).get(name, 0.0)
        m = ang.shape[0]
        axis = int(np.argmax(np.abs(rat[0]))) if kind == "spin" else None
        geo.append(
            StepGeometry(
                name, kind, gravity_in_body(a, g), body_rate(a, rat), np.full(m, 2000.0 / m), body_to_nav(a), axis
            )
        )
    return geo


def _solve(geo_ref: list[StepGeometry], geo_true: list[StepGeometry]) -> tuple[np.ndarray, np.ndarray]:
    """Noise-free information solution with z = f_out(true geometry) − f_ref (reference geometry)."""
    ri = 1.0 / NOISE_VAR
    a = np.diag(1.0 / PRIOR**2)
    v = np.zeros(18)
    for gr, gt in zip(geo_ref, geo_true, strict=True):
        z = _model(X_TRUE, gt.f, gt.omega) - gr.f
        h = design_matrix(gr.f, gr.omega)
        hw = np.transpose(h, (0, 2, 1)) * ri * gr.weight[:, None, None]
        a += np.einsum("kpa,kaq->pq", hw, h)
        v += np.einsum("kpa,ka->p", hw, z)
    p = np.linalg.inv(a)
    return p @ v, p


def test_the_budget_uses_the_one_model():
    """The budget takes the model specification (no model constants of its own): its H is the model's."""
    import analysis.identification.budget as budget_module
    from analysis.identification.specification import get_model

    assert not hasattr(budget_module, "design_matrix")
    geo = _geometry()[-1]
    _, h = budget_module._ht_rinv(geo, 1.0 / NOISE_VAR, get_model("accelerometer"))
    np.testing.assert_array_equal(h, design_matrix(geo.f, geo.omega))


def test_gravity_sensitivity_equals_the_re_solved_estimator():
    geo = _geometry()
    x0, p = _solve(geo, geo)
    np.testing.assert_allclose(x0, X_TRUE, rtol=1e-3)  # noise-free, full rank: the truth (up to the prior's pull)
    dg = 5e-4
    x1, _ = _solve(geo, _geometry(G + dg))  # the reference uses G, the world has G + dg
    s = gravity_sensitivity(p, geo, NOISE_VAR, G)
    # the true g exceeds the reference by dg: δx̂ = s·dg
    np.testing.assert_allclose(x1 - x0, s * dg, rtol=2e-3, atol=1e-3 * np.abs(s).max() * dg)
    # and it lands on the scale factors: S_i moves by δg/g·(1 + S_i) to first order
    np.testing.assert_allclose((x1 - x0)[3:6], dg / G * np.ones(3), rtol=2e-3)


def test_attitude_sensitivity_equals_the_re_solved_estimator():
    """Per-step nav-frame tilt δφ (C_b^n,true = R(δφ) C_b^n,reported): holds and spins."""
    geo = _geometry()
    _, p = _solve(geo, geo)
    rng = np.random.default_rng(4)
    dphi = {g.name: rng.normal(0, 5 * ARCSEC, 3) for g in geo}
    geo_true = []
    for g in geo:
        c_bn_true = Rotation.from_rotvec(dphi[g.name]).as_matrix() @ g.c_bn
        f_true = np.einsum("kab,a->kb", c_bn_true, np.array([0.0, 0.0, G]))  # C_n^b g_n
        geo_true.append(StepGeometry(g.name, g.kind, f_true, g.omega, g.weight, g.c_bn))
    x1, _ = _solve(geo, geo_true)
    sens = attitude_sensitivity(p, geo, NOISE_VAR)
    pred = sum(c @ dphi[g.name] for c, g in zip(sens, geo, strict=True))
    # first order: the neglected (S + T, D) × reference-error terms are ≲ 0.3 % of the effect
    np.testing.assert_allclose(x1 - _solve(geo, geo)[0], pred, rtol=1e-2, atol=1e-3 * np.abs(pred).max())


def _budget(p, geo, **kw):
    base = dict(g=G, g_uncertainty=3e-4, g_source="WGS-84", attitude_accuracy=1 * ARCSEC)
    base.update(kw)
    return build_budget(p + np.diag(np.diag(p)) * 0.5, p, geo, NOISE_VAR, **base)


def test_budget_starts_from_the_identification_covariance_and_adds_type_b_in_quadrature():
    geo = _geometry()
    _, p = _solve(geo, geo)
    b1 = _budget(p, geo)
    b2 = _budget(p, geo, attitude_accuracy=10 * ARCSEC)
    std1 = {c.key: c.std for c in b1.components}
    std2 = {c.key: c.std for c in b2.components}
    # white noise + bias instability = the identification's own covariance, unchanged
    cov1 = {c.key: c.covariance for c in b1.components}
    np.testing.assert_allclose(cov1["white_noise"] + cov1["bias_instability"], p + np.diag(np.diag(p)) * 0.5)
    np.testing.assert_allclose(std2["attitude"], 10 * std1["attitude"], rtol=1e-12)
    # the table's rate accuracy is no input: the spins' reference rate is the encoder angle over time
    keys = {c.key for c in b1.components}
    assert keys == {"white_noise", "bias_instability", "attitude", "local_g", "model_mismatch"}
    np.testing.assert_allclose(b1.combined**2, sum(v**2 for v in std1.values()), rtol=1e-12)
    np.testing.assert_allclose(b1.expanded, 2 * b1.combined)
    # local g at 30 mGal dominates the scale factors (≈ 30.6 ppm) and does nothing to the biases
    assert np.all(np.abs(std1["local_g"][3:6] / PPM - 3e-4 / G / PPM) < 0.5)
    assert np.all(std1["local_g"][0:3] < 1e-3 * std1["white_noise"][0:3])


def test_mismatch_counts_only_step_scatter_beyond_what_the_budget_claims():
    geo = _geometry()
    rng = np.random.default_rng(5)
    sig_dc = np.array([4 * UG, 0.0, 2 * UG])
    claimed = {g.name: np.array([1 * UG, 1 * UG, 1 * UG]) ** 2 for g in geo}
    obs_all, exc_all = [], []
    for _ in range(200):
        rows = []
        for g in geo:
            n = g.samples
            mean = rng.normal(0, np.sqrt(NOISE_VAR / n)) + rng.normal(0, 1, 3) * np.sqrt(sig_dc**2 + claimed[g.name])
            rows.append({"name": g.name, "samples": n, "mean": mean.tolist(), "rms": list(np.sqrt(NOISE_VAR))})
        obs, exc = mismatch_variance(geo, rows, NOISE_VAR, claimed, n_params_per_axis=0)
        obs_all.append(obs)
        exc_all.append(obs - (NOISE_VAR / geo[0].samples + 1 * UG**2))
    # unbiased on average for the injected excess (no fit here: 0 parameters removed)
    est = np.mean(exc_all, axis=0)
    np.testing.assert_allclose(np.sqrt(np.clip(est[[0, 2]], 0, None)), sig_dc[[0, 2]], rtol=0.1)
    assert abs(est[1]) < 0.3 * UG**2 * 4


def test_step_offsets_propagate_like_a_re_solved_estimator():
    geo = _geometry()
    _, p = _solve(geo, geo)
    rng = np.random.default_rng(6)
    off = {g.name: rng.normal(0, 3 * UG, 3) for g in geo}
    ri = 1.0 / NOISE_VAR
    v = np.zeros(18)
    for g in geo:
        h = design_matrix(g.f, g.omega)
        v += np.einsum("kpa,a->p", np.transpose(h, (0, 2, 1)) * ri * g.weight[:, None, None], off[g.name])
    direct = p @ v
    pred = sum(b @ off[g.name] for b, g in zip(step_offset_sensitivity(p, geo, NOISE_VAR), geo, strict=True))
    np.testing.assert_allclose(pred, direct, rtol=1e-10, atol=1e-20)
    # information matrices compared on their own scale, element (i, j) against √(A_ii A_jj): an off-diagonal sum
    # that cancels to ~0 keeps only rounding of its terms, which depends on the order the terms are added in
    info = data_information(geo, NOISE_VAR)
    scale = np.sqrt(np.outer(np.diag(info), np.diag(info)))
    np.testing.assert_allclose((np.linalg.inv(p) - np.diag(1 / PRIOR**2)) / scale, info / scale, rtol=0, atol=1e-9)


def test_bad_covariance_is_refused_with_a_clear_message():
    with pytest.raises(ValueError, match="18 × 18"):
        build_budget(
            np.eye(3), np.eye(18), [], NOISE_VAR, g=G, g_uncertainty=1e-6, g_source="measured",
            attitude_accuracy=0.0,
        )  # fmt: skip


def _tilted_geometry(e1: float, e2: float) -> list[StepGeometry]:
    """The ten-step geometry on a table whose middle axis is tilted by e1 (about the outer frame's y) and inner
    axis by e2 (about the middle frame's z), written with scipy rotations (independent of table_axes):
    C_t^n = R_z(ψ) R_y(e1) R_x(θ) R_z(e2) R_y(γ), ω^t summed axis by axis, gimbal angles/rates carried."""
    geo = []
    for name, kind, ang, rat in _ten_step_angles():
        m = ang.shape[0]
        rz, rx, ry = (Rotation.from_rotvec(np.outer(ang[:, i], np.eye(3)[j])) for i, j in ((0, 2), (1, 0), (2, 1)))
        t1, t2 = Rotation.from_rotvec([0.0, e1, 0.0]), Rotation.from_rotvec([0.0, 0.0, e2])
        inner = t2 * ry  # C_t^m
        mid = t1 * rx * inner  # C_t^o
        c_tn = (rz * mid).as_matrix()
        w = rat[:, 0:1] * mid.inv().apply([0, 0, 1.0]) + rat[:, 1:2] * inner.inv().apply([1.0, 0, 0])
        w = w + rat[:, 2:3] * np.array([0.0, 1.0, 0.0])
        f = G * c_tn[:, 2, :]  # C_n^b g e_Up (mounting = identity)
        axis = int(np.argmax(np.abs(rat[0]))) if kind == "spin" else None
        geo.append(StepGeometry(name, kind, f, w, np.full(m, 2000.0 / m), c_tn, axis, angles=ang, rates=rat))
    return geo


def test_mismatch_does_not_count_again_what_a_run_common_input_leaves_in_the_residuals():
    """The axis non-orthogonality is one draw for the run: the fit absorbs part of it and leaves a pattern in
    the step means. That pattern is the input's own (its component claims it); the mismatch test must expect
    it, or it reports it as model mismatch and the budget counts it twice (issue 24's coverage)."""
    from analysis.identification.budget import input_step_variance
    from analysis.identification.specification import get_model
    from analysis.identification.table_axes import orthogonality_input

    bound = 2 * ARCSEC
    ref = _tilted_geometry(0.0, 0.0)
    _, p = _solve(ref, ref)
    tiny = np.full(3, 1e-30)
    model = get_model()
    (inp,) = orthogonality_input(model, bound, G, "test")
    pre, post = input_step_variance(inp, p, ref, NOISE_VAR, model)
    assert not pre  # one draw for the run: nothing before the fit
    # the step-mean residuals of noise-free solves on tilted tables, one tilt at a time
    means = []
    for e in ((bound, 0.0), (0.0, bound)):
        geo_true = _tilted_geometry(*e)
        x_hat, _ = _solve(ref, geo_true)
        rows = []
        for gr, gt in zip(ref, geo_true, strict=True):
            res = _model(X_TRUE, gt.f, gt.omega) - gr.f - np.einsum("kan,n->ka", design_matrix(gr.f, gr.omega), x_hat)
            rows.append(np.average(res, axis=0, weights=gr.weight))
        means.append(np.array(rows))
    # E over ε_i uniform in ±bound (u² = bound²/3): Σ_s m_s² = (Σ R_1² + Σ R_2²) / 3
    expected = (np.sum(means[0] ** 2, axis=0) + np.sum(means[1] ** 2, axis=0)) / 3
    claimed = sum(post.values())
    assert np.all(expected[[0, 2]] > 0)
    np.testing.assert_allclose(claimed, expected, rtol=0.02, atol=1e-6 * expected.max())
    # step means realising exactly that expectation (ε = (±u, ±u), all four signs): no mismatch left
    u = bound / math.sqrt(3)
    obs_rows, fitted = [], {g.name: post[g.name] for g in ref}
    for s1 in (-1, 1):
        for s2 in (-1, 1):
            m = (s1 * means[0] + s2 * means[1]) * u / bound
            obs_rows += [
                {"name": g.name + f"/{s1}{s2}", "samples": 10**6, "mean": m[k].tolist()} for k, g in enumerate(ref)
            ]
    geo4 = [
        StepGeometry(g.name + f"/{s1}{s2}", g.kind, g.f, g.omega, g.weight)
        for s1 in (-1, 1)
        for s2 in (-1, 1)
        for g in ref
    ]
    fit4 = {g.name + f"/{s1}{s2}": fitted[g.name] for s1 in (-1, 1) for s2 in (-1, 1) for g in ref}
    _, without = mismatch_variance(geo4, obs_rows, tiny, {}, 6 * 4)
    _, with_fit = mismatch_variance(geo4, obs_rows, tiny, {}, 6 * 4, fit4)
    assert np.all(without[[0, 2]] > 0)  # the pattern, seen as mismatch
    np.testing.assert_allclose(with_fit, 0.0, atol=1e-3 * without.max())

"""The GUM budget's per-evaluation memo (analysis.identification.budget.StepTerms) and the table-axis chain reuse:
two geometries of different mountings in one process each get their own budget, equal to an independent,
uncached evaluation of the module's formulas; a memo handed a geometry it was not made for is not used."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from analysis.identification.budget import (
    BudgetInput,
    StepGeometry,
    StepTerms,
    build_budget,
    data_information,
    input_component,
    input_sensitivity,
    input_step_variance,
    mismatch_variance,
    reference_inputs,
)
from analysis.identification.gyro_budget import earth_rate_inputs
from analysis.identification.specification import UnitModel, get_model
from analysis.identification.table_axes import held_angle_input, orthogonality_input
from analysis.units import ARCSEC, DEG

UNIT = UnitModel((get_model("accelerometer"), get_model("gyro")))
G = 9.80665
LAT = math.radians(52.0)
EARTH_N = 7.292115e-5 * np.array([0.0, math.cos(LAT), math.sin(LAT)])
NOISE = np.array([1e-6] * 3 + [1e-10] * 3)


def _chain(ang: np.ndarray, rat: np.ndarray, e1: float = 0.0, e2: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """C_t^n and ω^t of a table whose middle axis is tilted by e1 (about the outer frame's y) and inner axis by e2
    (about the middle frame's z), with scipy rotations (independent of analysis.identification.table_axes):
    C_t^n = R_z(ψ) R_y(e1) R_x(θ) R_z(e2) R_y(γ); ω^t = ψ̇ (C_t^o)ᵀ e_z + θ̇ (C_t^m)ᵀ e_x + γ̇ e_y."""
    m = ang.shape[0]

    def rot(axis: int, angle: np.ndarray | float) -> Rotation:
        return Rotation.from_rotvec(np.outer(np.broadcast_to(angle, (m,)), np.eye(3)[axis]))

    c_tm = rot(2, e2) * rot(1, ang[:, 2])
    c_to = rot(1, e1) * rot(0, ang[:, 1]) * c_tm
    c_tn = (rot(2, ang[:, 0]) * c_to).as_matrix()
    c_to, c_tm = c_to.as_matrix(), c_tm.as_matrix()
    w_t = rat[:, 0:1] * c_to[:, 2, :] + rat[:, 1:2] * c_tm[:, 0, :] + rat[:, 2:3] * np.array([0.0, 1.0, 0.0])
    return c_tn, w_t


def _reference(ang: np.ndarray, rat: np.ndarray, mount: np.ndarray, e1: float = 0.0, e2: float = 0.0) -> np.ndarray:
    """[f, ω_ib] (m, 6) in the body frame (mounting C_b^t = ``mount``): f = C_n^b g e_Up,
    ω_ib = C_t^b ω^t + C_n^b Ω^n."""
    c_tn, w_t = _chain(ang, rat, e1, e2)
    c_bn = c_tn @ mount
    return np.concatenate([G * c_bn[:, 2, :], w_t @ mount + EARTH_N @ c_bn], axis=1)


def _naive_shape(key: str, s: StepGeometry, mount: np.ndarray) -> np.ndarray | None:
    """The table-axis inputs' shapes as central differences of :func:`_reference` (step 1e-5 rad)."""
    h = 1e-5
    if key == "axis_orthogonality":
        cols = [_reference(s.angles, s.rates, mount, *(h * d)) - _reference(s.angles, s.rates, mount, *(-h * d))
                for d in np.eye(2)]  # fmt: skip
        return np.stack(cols, axis=2) / (2 * h)
    if s.held_angle_u is None:
        return None
    cols = [(_reference(s.angles + h * d, s.rates, mount) - _reference(s.angles - h * d, s.rates, mount)) / (2 * h)
            * s.held_angle_u[j] for j, d in enumerate(np.eye(3))]  # fmt: skip
    return np.stack(cols, axis=2)


def _step(name: str, kind: str, ang: np.ndarray, rat: np.ndarray, mount: np.ndarray) -> StepGeometry:
    """A step's reference on a table with mounting C_b^t = ``mount`` (frames: n ENU, t inner gimbal, b body):
    C_b^n = C_t^n C_b^t, f = C_n^b g e_Up, ω^b = C_t^b ω^t, Ω^b = C_n^b Ω^n."""
    m = ang.shape[0]
    c_tn, w_t = _chain(ang, rat)
    c_bn = c_tn @ mount
    spin = int(np.argmax(np.abs(rat[0]))) if kind == "spin" else None
    held = None if spin is None else np.where(np.arange(3) == spin, 0.0, 3 * ARCSEC)
    return StepGeometry(
        name, kind, G * c_bn[:, 2, :], w_t @ mount, np.full(m, 1000.0 / m), c_bn, spin, (0.0, 1.0),
        np.einsum("nji,j->ni", c_bn, EARTH_N), ang, rat, held,
    )  # fmt: skip


def _geometry(mount: np.ndarray) -> list[StepGeometry]:
    r = math.radians
    out = []
    for grp, base, axis in (("A", (0.0, 0.0, 0.0), 2), ("B", (r(-90), r(-90), 0.0), 1), ("C", (r(90), 0.0, r(90)), 1)):
        for k in range(4):
            a = np.tile(np.array(base), (3, 1))
            a[:, axis] += r(90 * k) + np.array([-1e-5, 0.0, 1e-5])
            out.append(_step(f"{grp}/hold-{k}", "hold", a, np.zeros((3, 3)), mount))
        a = np.tile(np.array(base), (24, 1))
        a[:, axis] += np.linspace(0, 2 * np.pi, 24, endpoint=False)
        rates = np.zeros((24, 3))
        rates[:, axis] = 20 * DEG
        out.append(_step(f"{grp}/spin", "spin", a, rates, mount))
    outer = np.tile(np.array([0.3, 0.2, -0.4]), (24, 1))
    outer[:, 0] += np.linspace(0, 2 * np.pi, 24, endpoint=False)
    rates = np.zeros((24, 3))
    rates[:, 0] = 20 * DEG
    out.append(_step("D/spin", "spin", outer, rates, mount))  # an outer-axis spin: the middle tilt ε₁ shows
    return out


def _inputs(geo: list[StepGeometry]) -> list[BudgetInput]:
    return [
        *reference_inputs(UNIT, geo, g=G, g_uncertainty=3e-4, g_source="test", attitude_accuracy=5 * ARCSEC),
        *earth_rate_inputs(UNIT, LAT, 20 * ARCSEC, 1 * ARCSEC),
        *orthogonality_input(UNIT, 5 * ARCSEC, G, "test"),
        *held_angle_input(UNIT, G),
    ]


def _a_inv(geo: list[StepGeometry]) -> np.ndarray:
    prior = np.diag(1.0 / UNIT.reference_scale**2) if np.all(UNIT.reference_scale > 0) else np.eye(UNIT.n_params)
    return np.linalg.inv(prior + data_information(geo, NOISE, UNIT))


def _rows(geo: list[StepGeometry]) -> list[dict[str, object]]:
    rng = np.random.default_rng(11)
    return [
        {"name": s.name, "samples": 1000, "mean": (rng.normal(size=6) * np.sqrt(NOISE) * 0.3).tolist()} for s in geo
    ]


def _naive_sensitivity(a_inv, geo, shapes):  # type: ignore[no-untyped-def]
    """A⁻¹ Σ_k w_k H_kᵀ R⁻¹ e_k per step, point by point (no einsum, no memo), for the steps' shapes."""
    out = []
    for s, e in zip(geo, shapes, strict=True):
        if e is None:
            out.append(None)
            continue
        h = UNIT.design_matrix(s.f, s.omega, s.earth)
        acc = np.zeros((UNIT.n_params, e.shape[2]))
        for k in range(h.shape[0]):
            acc += s.weight[k] * h[k].T @ np.diag(1.0 / NOISE) @ e[k]
        out.append(a_inv @ acc)
    return out


def _naive_budget(geo: list[StepGeometry], a_inv: np.ndarray, mount: np.ndarray) -> dict[str, np.ndarray]:
    """Every input's component and the model-mismatch component from the module docstring's formulas; the
    table-axis inputs' shapes from this file's own gimbal chain (:func:`_naive_shape`)."""
    comps: dict[str, np.ndarray] = {}
    expected = {s.name: np.zeros(6) for s in geo}
    fitted = {s.name: np.zeros(6) for s in geo}
    for inp in _inputs(geo):
        table_axis = inp.key in ("axis_orthogonality", "held_angles")
        shapes = [_naive_shape(inp.key, s, mount) if table_axis else inp.shape(s) for s in geo]
        sens = _naive_sensitivity(a_inv, geo, shapes)
        live = [c for c in sens if c is not None]
        if inp.per_step:
            comps[inp.key] = sum(c @ inp.covariance @ c.T for c in live)
        else:
            c_run = sum(live)
            comps[inp.key] = c_run @ inp.covariance @ c_run.T
        for s, e in zip(geo, shapes, strict=True):
            if inp.per_step and e is not None:
                mean = np.average(e, axis=0, weights=s.weight)
                expected[s.name] = expected[s.name] + np.diag(mean @ inp.covariance @ mean.T)
            elif not inp.per_step:
                res = -np.einsum("kan,nb->kab", UNIT.design_matrix(s.f, s.omega, s.earth), c_run)
                mean = np.average(res if e is None else res + e, axis=0, weights=s.weight)
                fitted[s.name] = fitted[s.name] + np.diag(mean @ inp.covariance @ mean.T)
    npa = [len(ax) for ax in UNIT.axis_params]
    _, excess = mismatch_variance(geo, _rows(geo), NOISE, expected, npa, fitted)
    offsets = [a_inv @ sum(s.weight[k] * UNIT.design_matrix(s.f, s.omega, s.earth)[k].T @ np.diag(1.0 / NOISE)
                           for k in range(s.weight.size)) for s in geo]  # fmt: skip
    comps["model_mismatch"] = sum(b @ np.diag(excess) @ b.T for b in offsets)
    return comps


def _budget(geo: list[StepGeometry], a_inv: np.ndarray) -> dict[str, np.ndarray]:
    extra = [i for i in _inputs(geo) if i.key not in ("attitude", "local_g")]
    b = build_budget(
        a_inv, a_inv, geo, NOISE, g=G, g_uncertainty=3e-4, g_source="test", attitude_accuracy=5 * ARCSEC,
        residuals_per_step=_rows(geo), model=UNIT, extra_inputs=extra,
    )  # fmt: skip
    return {c.key: c.covariance for c in b.components}


def test_two_mountings_in_one_process_each_get_their_own_budget_equal_to_the_uncached_formulas():
    """Budgets of two mountings (the same gimbal angles), formed one after the other in one process, each equal an
    independent evaluation; forming the first again after the second gives it bit for bit (nothing of one
    geometry is reused for the other: a memo or chain cache keyed on the angles alone, or kept across calls,
    fails here)."""
    mount_b = Rotation.from_euler("XYZ", [0.4, -1.1, 2.3]).as_matrix()
    geo_a, geo_b = _geometry(np.eye(3)), _geometry(mount_b)
    a_inv_a, a_inv_b = _a_inv(geo_a), _a_inv(geo_b)
    first = _budget(geo_a, a_inv_a)
    second = _budget(geo_b, a_inv_b)
    again = _budget(geo_a, a_inv_a)
    for key in first:
        assert first[key].tobytes() == again[key].tobytes(), key
    for got, geo, a_inv, mount in ((first, geo_a, a_inv_a, np.eye(3)), (second, geo_b, a_inv_b, mount_b)):
        ref = _naive_budget(geo, a_inv, mount)
        for key, cov in ref.items():
            assert np.max(np.abs(cov)) > 0, key  # every component really evaluated
            # the finite differences' truncation (~1e-10 relative) and rounding (~1e-11) bound the agreement
            np.testing.assert_allclose(got[key], cov, rtol=1e-7, atol=1e-9 * np.max(np.abs(cov)), err_msg=key)
    # the mountings' budgets really differ where the mounting matters (the table-axis and Earth-rate inputs)
    for key in ("axis_orthogonality", "held_angles", "azimuth"):
        assert not np.allclose(first[key], second[key], rtol=1e-3, atol=0.0), key


def test_a_memo_made_for_another_geometry_is_not_used():
    """The memo is keyed by the objects it was made for: handed another geometry (or another A⁻¹), the functions
    compute afresh, so the answer is that geometry's own."""
    mount_b = Rotation.from_euler("XYZ", [0.4, -1.1, 2.3]).as_matrix()
    geo_a, geo_b = _geometry(np.eye(3)), _geometry(mount_b)
    a_inv = _a_inv(geo_a)
    inp = next(i for i in _inputs(geo_a) if i.key == "axis_orthogonality")
    memo = StepTerms(a_inv, geo_a, NOISE, UNIT)
    input_component(inp, a_inv, geo_a, NOISE, UNIT, terms=memo)  # fills the memo with geometry A's terms
    for geo, a in ((geo_b, a_inv), (geo_a, a_inv * 1.5)):
        with_memo = input_component(inp, a, geo, NOISE, UNIT, terms=memo).covariance
        fresh = input_component(inp, a, geo, NOISE, UNIT).covariance
        assert with_memo.tobytes() == fresh.tobytes()
        pre_m, post_m = input_step_variance(inp, a, geo, NOISE, UNIT, terms=memo)
        pre_f, post_f = input_step_variance(inp, a, geo, NOISE, UNIT)
        assert pre_m.keys() == pre_f.keys() and all(post_m[k].tobytes() == post_f[k].tobytes() for k in post_f)
    assert not np.allclose(
        input_component(inp, a_inv, geo_b, NOISE, UNIT, terms=memo).covariance,
        input_component(inp, a_inv, geo_a, NOISE, UNIT, terms=memo).covariance,
        rtol=1e-3,
        atol=0.0,
    )


@pytest.mark.parametrize("per_step", [False, True])
def test_each_steps_shape_is_evaluated_once_per_budget(per_step: bool):
    """The memo's point: an input's shape is formed once per step per budget (not once per use: component,
    sensitivity, mismatch pre/post-fit), and with the memo the sensitivities equal the uncached ones."""
    geo = _geometry(np.eye(3))
    a_inv = _a_inv(geo)
    calls: list[str] = []
    base = next(i for i in _inputs(geo) if i.key == "axis_orthogonality")

    def shape(s: StepGeometry) -> np.ndarray | None:
        calls.append(s.name)
        return base.shape(s)

    counted = BudgetInput("counted", "counted", "test", base.covariance, shape, per_step=per_step)
    build_budget(
        a_inv, a_inv, geo, NOISE, g=G, g_uncertainty=3e-4, g_source="test", attitude_accuracy=5 * ARCSEC,
        residuals_per_step=_rows(geo), model=UNIT, extra_inputs=[counted],
    )  # fmt: skip
    assert sorted(calls) == sorted(s.name for s in geo)
    memo = StepTerms(a_inv, geo, NOISE, UNIT)
    for got, ref in zip(input_sensitivity(a_inv, geo, NOISE, base.shape, UNIT, terms=memo),
                        _naive_sensitivity(a_inv, geo, [base.shape(s) for s in geo]), strict=True):  # fmt: skip
        np.testing.assert_allclose(got, ref, rtol=1e-9, atol=1e-12 * np.max(np.abs(ref)))


def test_a_derived_shape_forms_its_base_once_per_step_and_gives_the_direct_numbers():
    """The gyro's azimuth input is the attitude shape about the vertical: through the memo the base is formed once per
    step for both inputs, and the derived component is bit for bit the one of the direct function. Attitude shapes
    are one memo entry only for the same model object (another object of the same structure is another entry)."""
    from analysis.identification.budget import AttitudeShape, DerivedShape, attitude_shape

    geo = _geometry(np.eye(3))
    a_inv = _a_inv(geo)
    up = np.array([0.0, 0.0, 1.0])
    calls: list[str] = []

    def base(s: StepGeometry) -> np.ndarray:
        calls.append(s.name)
        return attitude_shape(s, UNIT)

    def about_up(e: np.ndarray) -> np.ndarray:
        return (e @ up)[:, :, None]

    cov1 = np.array([[(20 * ARCSEC) ** 2]])
    att = BudgetInput("att", "att", "test", np.eye(3) * (3 * ARCSEC) ** 2, base, per_step=True)
    az = BudgetInput("az", "az", "test", cov1, DerivedShape(base, about_up))
    b = build_budget(
        a_inv, a_inv, geo, NOISE, g=G, g_uncertainty=3e-4, g_source="test", attitude_accuracy=5 * ARCSEC,
        residuals_per_step=_rows(geo), model=UNIT, extra_inputs=[att, az],
    )  # fmt: skip
    assert sorted(calls) == sorted(s.name for s in geo)
    direct = BudgetInput("az", "az", "test", cov1, lambda s: (attitude_shape(s, UNIT) @ up)[:, :, None])
    got = next(c for c in b.components if c.key == "az").covariance
    assert got.tobytes() == input_component(direct, a_inv, geo, NOISE, UNIT).covariance.tobytes()
    assert np.max(np.abs(got)) > 0
    twin = UnitModel((get_model("accelerometer"), get_model("gyro")))
    assert AttitudeShape(UNIT) == AttitudeShape(UNIT) and hash(AttitudeShape(UNIT)) == hash(AttitudeShape(UNIT))
    assert AttitudeShape(UNIT) != AttitudeShape(twin)

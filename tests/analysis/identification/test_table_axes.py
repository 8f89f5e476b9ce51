"""The table-axis non-orthogonality input against the simulator's own kinematics (an independent implementation)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from analysis import gimbal
from analysis.identification.budget import StepGeometry
from analysis.identification.specification import UnitModel, get_model
from analysis.identification.table_axes import orthogonality_shape, tilted_chain
from analysis.units import ARCSEC, DEG
from drivers.sim.config import SimConfig, TableModel
from drivers.sim.world import SimulatedWorld

UNIT = UnitModel((get_model("accelerometer"), get_model("gyro")))


def _world(e1: float, e2: float) -> SimulatedWorld:
    return SimulatedWorld(SimConfig(table=replace(TableModel(), non_orthogonality=(e1, e2))), 0)


def test_tilted_chain_equals_the_simulators_kinematics():
    rng = np.random.default_rng(3)
    ang = rng.uniform(-np.pi, np.pi, (50, 3))
    rat = rng.uniform(-1.0, 1.0, (50, 3))
    e1, e2 = 40 * ARCSEC, -25 * ARCSEC
    c_bn, omega_b, _ = _world(e1, e2)._kinematics(ang, rat, np.zeros((50, 3)))
    c_tn, omega_t = tilted_chain(ang, rat, e1, e2)
    np.testing.assert_allclose(c_tn, c_bn, atol=1e-14)  # identity mounting
    np.testing.assert_allclose(omega_t, omega_b, atol=1e-14)


def _spin_geometry(axis: int, angles: list[float], rate: float, g: float = 9.8) -> StepGeometry:
    ang = np.tile(np.array(angles, float), (36, 1))
    ang[:, axis] += np.linspace(0, 2 * np.pi, 36, endpoint=False)
    rat = np.zeros((36, 3))
    rat[:, axis] = rate
    c_bn = gimbal.body_to_nav(ang)
    earth_n = np.array([0.0, 5e-5, 5.5e-5])
    earth = np.einsum("nji,j->ni", c_bn, earth_n)
    return StepGeometry(
        "spin", "spin", gimbal.gravity_in_body(ang, g), gimbal.body_rate(ang, rat), np.ones(36), c_bn, axis,
        (0.0, 1.0), earth, ang, rat,
    )  # fmt: skip


def test_shape_is_the_derivative_of_the_simulated_reference_and_inner_spins_see_no_tilt():
    g = 9.8
    for axis, angles in ((0, [0.0, 0.3, -0.2]), (1, [0.4, 0.0, 0.7]), (2, [0.1, 0.5, 0.0])):
        geo = _spin_geometry(axis, angles, 60 * DEG, g)
        sh = orthogonality_shape(geo, UNIT, g)
        assert sh is not None and sh.shape == (36, 6, 2)
        for k in range(2):
            e = np.zeros(2)
            e[k] = 2 * ARCSEC
            c1, w1, _ = _world(*e)._kinematics(geo.angles, geo.rates, np.zeros((36, 3)))
            c0, w0, _ = _world(0.0, 0.0)._kinematics(geo.angles, geo.rates, np.zeros((36, 3)))
            earth_n = np.array([0.0, 5e-5, 5.5e-5])
            df = g * (c1[:, 2, :] - c0[:, 2, :])
            dw = (w1 - w0) + (earth_n @ c1 - earth_n @ c0)
            # first order: the finite tilt's second-order term is ≲ (value) × e²
            np.testing.assert_allclose(sh[:, :3, k] * e[k], df, atol=2 * g * e[k] ** 2)
            np.testing.assert_allclose(sh[:, 3:, k] * e[k], dw, atol=2 * 60 * DEG * e[k] ** 2 + 1e-18)
            assert np.max(np.abs(df)) > 100 * 2 * g * e[k] ** 2  # and the first-order term is really there
        table_part = sh[:, 3:, :] - orthogonality_shape(replace(geo, earth=None), UNIT, g)[:, 3:, :]
        spin_part = sh[:, 3:, :] - table_part  # the tilt of the spin axis in the body frame (Earth rate removed)
        if axis == 2:
            np.testing.assert_allclose(spin_part, 0.0, atol=1e-12)  # the inner axis is the body's own
        else:
            assert np.max(np.abs(spin_part)) > 0.5 * 60 * DEG  # ≈ |ω| per rad of tilt


def test_held_angle_shape_is_the_simulated_reference_with_a_held_gimbal_turned_and_zero_for_holds():
    """A held gimbal's angle off by δ during a spin (its mean reading's error, issue 25): the simulator's kinematics
    at the turned angle less at the reported one is the shape × δ/u, for both triads; the spinning gimbal's
    column is 0; a middle-axis spin's axis turns in the body frame by δ (|δω| = |ω| δ) when the inner gimbal is
    off; a hold has no such input."""
    from analysis.identification.table_axes import held_angle_shape

    g, rate = 9.8, 60 * DEG
    earth_n = np.array([0.0, 5e-5, 5.5e-5])
    for axis, angles in ((0, [0.0, 0.3, -0.2]), (1, [0.4, 0.0, np.pi / 2]), (2, [0.1, 0.5, 0.0])):
        u = np.array([3e-8, 2e-8, 4e-8])
        u[axis] = 0.0
        geo = replace(_spin_geometry(axis, angles, rate, g), held_angle_u=u)
        sh = held_angle_shape(geo, UNIT, g)
        assert sh is not None and sh.shape == (36, 6, 3)
        np.testing.assert_array_equal(sh[:, :, axis], 0.0)
        w = _world(0.0, 0.0)
        c0, w0, _ = w._kinematics(geo.angles, geo.rates, np.zeros((36, 3)))
        for j in {0, 1, 2} - {axis}:
            d = np.zeros(3)
            d[j] = 1 * ARCSEC
            c1, w1, _ = w._kinematics(geo.angles + d, geo.rates, np.zeros((36, 3)))
            df, dw = g * (c1[:, 2, :] - c0[:, 2, :]), (w1 - w0) + (earth_n @ c1 - earth_n @ c0)
            np.testing.assert_allclose(sh[:, :3, j] / u[j] * d[j], df, atol=2 * g * d[j] ** 2)
            np.testing.assert_allclose(sh[:, 3:, j] / u[j] * d[j], dw, atol=2 * rate * d[j] ** 2 + 1e-18)
        if axis == 1:  # inner gimbal held at 90°: the middle spin's axis turns by δ_γ about body y
            spin_part = held_angle_shape(replace(geo, earth=None), UNIT, g)[:, 3:, 2] / u[2]  # Earth rate left out
            np.testing.assert_allclose(np.linalg.norm(spin_part, axis=1), rate, rtol=1e-6)
            np.testing.assert_allclose(spin_part[:, 1], 0.0, atol=1e-12)  # perpendicular to the inner axis (body y)
    hold = replace(_spin_geometry(1, [0.4, 0.0, 0.7], 0.0, g), kind="hold", spin_axis=None)
    assert held_angle_shape(hold, UNIT, g) is None

"""analysis.gimbal: a navigation-frame vector rotated into the body frame sample by sample (issue 32) equals
the transpose of the direction-cosine matrix applied to it, and scipy's rotation (an independent reference)."""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from analysis import gimbal
from analysis.gimbal import body_to_nav, nav_to_body


def test_nav_to_body_is_the_transposed_attitude_applied_to_the_vector():
    rng = np.random.default_rng(3)
    ang = rng.uniform(-np.pi, np.pi, (500, 3))
    mounting = Rotation.from_euler("xyz", [0.3, -0.2, 1.1]).as_matrix()
    v = np.array([0.0, 4.87e-5, 5.42e-5])
    for m in (None, mounting):
        ref = np.einsum("nji,j->ni", body_to_nav(ang, m), v)
        np.testing.assert_allclose(nav_to_body(ang, v, m), ref, rtol=0, atol=1e-15 * np.linalg.norm(v))
    c_tn = Rotation.from_euler("ZXY", ang).as_matrix()  # C_t^n = R_z(ψ) R_x(θ) R_y(γ)
    scipy_ref = np.einsum("nji,j->ni", c_tn @ mounting, v)
    np.testing.assert_allclose(nav_to_body(ang, v, mounting), scipy_ref, rtol=0, atol=1e-15 * np.linalg.norm(v))
    assert nav_to_body(ang[0], v).shape == (3,)


def test_shared_sines_and_cosines_give_the_same_bits_as_each_function_computing_its_own():
    """gravity_in_body, table_rate, body_rate and nav_to_body with the angles' angle_trig passed in return exactly
    (bit for bit) what they return computing the sines and cosines themselves."""
    rng = np.random.default_rng(3)
    ang = rng.uniform(-4.0, 4.0, (500, 3))
    rates = rng.normal(0.0, 1.0, (500, 3))
    mount = gimbal.table_to_nav(np.array([0.1, -0.2, 0.3]))
    trig = gimbal.angle_trig(ang)
    v = np.array([1e-5, 4e-5, -3e-5])
    for m in (None, mount):
        assert np.array_equal(gimbal.gravity_in_body(ang, 9.8, m, trig=trig), gimbal.gravity_in_body(ang, 9.8, m))
        assert np.array_equal(gimbal.body_rate(ang, rates, m, trig=trig), gimbal.body_rate(ang, rates, m))
        assert np.array_equal(gimbal.nav_to_body(ang, v, m, trig=trig), gimbal.nav_to_body(ang, v, m))
    assert np.array_equal(gimbal.table_rate(ang, rates, trig=trig), gimbal.table_rate(ang, rates))
    assert np.array_equal(trig[0], np.cos(ang[:, 0])) and np.array_equal(trig[5], np.sin(ang[:, 2]))

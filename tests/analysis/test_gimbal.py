"""analysis.gimbal: a navigation-frame vector rotated into the body frame sample by sample (issue 32) equals
the transpose of the direction-cosine matrix applied to it, and scipy's rotation (an independent reference)."""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

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

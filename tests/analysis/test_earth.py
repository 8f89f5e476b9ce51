"""WGS-84 normal gravity with the second-order height correction (NIMA TR8350.2 eq. 4-3)."""

from __future__ import annotations

import math

import pytest

from analysis.earth import normal_gravity


def test_on_the_ellipsoid_it_is_somigliana_at_equator_and_pole():
    # WGS-84 defining values: γ_e = 9.7803253359, γ_p = 9.8321849378 m/s²
    assert normal_gravity(0.0, 0.0) == pytest.approx(9.7803253359, abs=1e-10)
    assert normal_gravity(math.pi / 2, 0.0) == pytest.approx(9.8321849378, abs=1e-9)


def test_height_correction_is_second_order():
    phi = math.radians(45.0)
    g0 = normal_gravity(phi, 0.0)
    d1 = g0 - normal_gravity(phi, 1.0)
    # the linear gradient near 45° is the familiar 3.086e-6 (m/s²)/m
    assert d1 == pytest.approx(3.086e-6, rel=2e-3)
    # and the h² term: the curvature equals 3 γ / a² (a = 6378137 m)
    h = 2000.0
    second = normal_gravity(phi, h) - 2 * normal_gravity(phi, h / 2) + g0
    assert second == pytest.approx(2 * 3 * g0 / 6378137.0**2 * (h / 2) ** 2, rel=1e-6)
    # at 1450 m the second-order result differs from the linear free-air value by ≈ 0.3 ppm of g
    diff = normal_gravity(math.radians(48.15), 1450.0) - (normal_gravity(math.radians(48.15), 0.0) - 3.086e-6 * 1450)
    assert 0.1e-6 < diff / 9.8 < 0.6e-6

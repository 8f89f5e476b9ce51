"""analysis.gimbal's rotations written with scratch arrays and into the result's columns (issue 32) give what the
plain expressions of them give, bit for bit (signed zeros included): the expressions are written out here as the
module had them, on random attitudes at rest (rates ±0) and spinning, with and without a mounting, with and
without the shared sines and cosines, for one sample (3,), many (n, 3) and a grid (k, m, 3)."""

from __future__ import annotations

import numpy as np
import pytest

from analysis import gimbal


def _bits(a) -> np.ndarray:
    return np.ascontiguousarray(a, dtype=float).view(np.int64)


def _same(a, b) -> bool:
    return np.shape(a) == np.shape(b) and np.array_equal(_bits(a), _bits(b))


def _plain_nav_to_body(a, v, m):
    vx, vy, vz = (float(c) for c in v)
    cp, sp, ct, st, cg, sg = (f(a[..., k]) for k in range(3) for f in (np.cos, np.sin))
    x, y = cp * vx + sp * vy, cp * vy - sp * vx
    y, z = ct * y + st * vz, ct * vz - st * y
    out = np.empty(a.shape)
    out[..., 0] = cg * x - sg * z
    out[..., 1] = y
    out[..., 2] = sg * x + cg * z
    return out if m is None else out @ m


def _plain_table_rate(a, r):
    th, ga = a[..., 1], a[..., 2]
    psid, thd, gad = r[..., 0], r[..., 1], r[..., 2]
    v1x, v1y, v1z = thd, psid * np.sin(th), psid * np.cos(th)
    c, s = np.cos(ga), np.sin(ga)
    out = np.empty(np.broadcast_shapes(a.shape, r.shape))
    out[..., 0] = c * v1x - s * v1z
    out[..., 1] = v1y + gad
    out[..., 2] = s * v1x + c * v1z
    return out


def _plain_gravity(a, g, m):
    th, ga = a[..., 1], a[..., 2]
    row = np.empty(a.shape)
    row[..., 0] = -np.cos(th) * np.sin(ga)
    row[..., 1] = np.sin(th)
    row[..., 2] = np.cos(th) * np.cos(ga)
    if m is not None:
        row = row @ m
    return g * row


@pytest.mark.parametrize("shape", [(3,), (400, 3), (7, 9, 3)])
@pytest.mark.parametrize("spinning", [False, True])
def test_rotations_are_the_plain_expressions_bit_for_bit(shape, spinning: bool) -> None:
    rng = np.random.default_rng(len(shape) + 10 * spinning)
    ang = rng.uniform(-4.0, 4.0, shape)
    flat = ang.reshape(-1, 3)
    flat[: min(2, flat.shape[0])] = [[0.0, -0.0, 0.0], [np.pi / 2, 0.0, -np.pi]][: flat.shape[0]]  # exact zeros
    rates = rng.normal(0.0, 1.5, shape) if spinning else np.where(rng.random(shape) < 0.5, -0.0, 0.0)
    mount = gimbal.table_to_nav(np.array([0.1, -0.2, 0.3]))
    v = np.array([0.0, 4.2e-5, 5.1e-5])
    trig = gimbal.angle_trig(ang)
    for m in (None, mount):
        for tr in (None, trig):
            assert _same(gimbal.nav_to_body(ang, v, m, trig=tr), _plain_nav_to_body(ang, v, m))
            assert _same(gimbal.gravity_in_body(ang, 9.80665, m, trig=tr), _plain_gravity(ang, 9.80665, m))
            w = _plain_table_rate(ang, rates)
            assert _same(gimbal.table_rate(ang, rates, trig=tr), w)
            assert _same(gimbal.body_rate(ang, rates, m, trig=tr), w if m is None else w @ m)
    one_rate = rates.reshape(-1, 3)[0]  # one rate for every sample (a spin's rate, broadcast)
    assert _same(gimbal.table_rate(ang, one_rate, trig=trig), _plain_table_rate(ang, one_rate))

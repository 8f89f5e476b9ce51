"""The regressors written column by column (issue 32) are the regressors as the model states them, bit for bit:
the accelerometer's [1, f, f∘f, c(ω)] (c from analysis.identification.model.centripetal), the gyro's
[1, ω_ib, f (, ω_ib∘ω_ib) (, |ω_ib|)], the unit's ideal output side by side, and the Gram formed from them the
way it is formed (one (n, columns) block, Aᵀ A) — at rest (ω all ±0) and spinning, with and without Earth rate."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from analysis.identification.gyro import GyroModel
from analysis.identification.model import ACCELEROMETER, centripetal
from analysis.identification.specification import ModelSpec, UnitModel


def _bits(a: np.ndarray) -> np.ndarray:
    return np.ascontiguousarray(a, dtype=float).view(np.int64)


def _same(a: np.ndarray, b: np.ndarray) -> bool:
    return a.shape == b.shape and np.array_equal(_bits(a), _bits(b))


def _samples(rng: np.random.Generator, n: int, spinning: bool):
    f = rng.normal(0.0, 6.0, (n, 3))
    if spinning:
        om = rng.normal(0.0, 2.0, (n, 3))
    else:  # a hold: the table rate is a signed zero per component
        om = np.where(rng.random((n, 3)) < 0.5, -0.0, 0.0)
    earth = rng.normal(0.0, 5e-5, (n, 3))
    return f, om, earth


def _accel_plain(f, om):
    return np.hstack([np.ones((f.shape[0], 1)), f, f * f, centripetal(om)])


def _gyro_plain(model: GyroModel, f, om, earth):
    w = om if earth is None else om + earth
    cols = [np.ones((f.shape[0], 1)), w, f]
    if model.quadratic:
        cols.append(w * w)
    if model.asymmetry:
        cols.append(np.abs(w))
    return np.hstack(cols)


@pytest.mark.parametrize("spinning", [False, True])
def test_accelerometer_regressors_are_the_stated_ones(spinning: bool) -> None:
    rng = np.random.default_rng(11)
    for n in (1, 7, 5000):
        f, om, earth = _samples(rng, n, spinning)
        assert _same(ACCELEROMETER.base_regressors(f, om, earth), _accel_plain(f, om))


@pytest.mark.parametrize("spinning", [False, True])
def test_gyro_regressors_are_the_stated_ones(spinning: bool) -> None:
    rng = np.random.default_rng(12)
    for full_g, quad, asym in itertools.product((False, True), repeat=3):
        model = GyroModel(full_g=full_g, quadratic=quad, asymmetry=asym)
        f, om, earth = _samples(rng, 3000, spinning)
        for ea in (None, earth):
            assert _same(model.base_regressors(f, om, ea), _gyro_plain(model, f, om, ea)), (full_g, quad, asym)


@pytest.mark.parametrize("spinning", [False, True])
def test_unit_ideal_output_and_gram_are_the_plain_ones(spinning: bool) -> None:
    """The unit model's ideal output (np.concatenate of its parts' before) and the Kalman filter's Gram with the
    measurement z (the block [regressors | z] per part, Aᵀ A), against the same formed from the stated pieces."""
    rng = np.random.default_rng(13)
    unit = UnitModel((ACCELEROMETER, GyroModel()))
    n = 4000
    f, om, earth = _samples(rng, n, spinning)
    y = np.hstack([f + rng.normal(0.0, 1e-3, (n, 3)), om + earth + rng.normal(0.0, 1e-5, (n, 3))])
    ideal = unit.ideal(f, om, earth)
    assert _same(ideal, np.concatenate([ACCELEROMETER.ideal(f, om, earth), GyroModel().ideal(f, om, earth)], axis=1))
    z = y - ideal
    gram = unit.regressor_gram(f, om, z, earth=earth)
    blocks = [np.hstack([_accel_plain(f, om), z[:, :3]]), np.hstack([_gyro_plain(GyroModel(), f, om, earth), z[:, 3:]])]
    expected = np.zeros_like(gram)
    off = 0
    for blk in blocks:
        blk = np.ascontiguousarray(blk)
        m = blk.shape[1]
        expected[off : off + m, off : off + m] = blk.T @ blk
        off += m
    assert _same(gram, expected)


@pytest.mark.parametrize("spinning", [False, True])
def test_gram_from_the_output_is_the_gram_from_z(spinning: bool) -> None:
    """regressor_gram(y=output) forms z = y − ideal in its blocks (each part's fill_measurement, the gyro's from
    its ω_ib regressors): the same Gram as passing z, bit for bit; the generic fill_measurement (a model without
    its own) agrees with each part's."""
    rng = np.random.default_rng(14)
    n = 3000
    f, om, earth = _samples(rng, n, spinning)
    for parts in ((ACCELEROMETER,), (ACCELEROMETER, GyroModel()), (ACCELEROMETER, GyroModel(quadratic=True))):
        unit = parts[0] if len(parts) == 1 else UnitModel(parts)
        y = unit.ideal(f, om, earth) + rng.normal(0.0, 1e-3, (n, unit.n_axes))
        for ea in (None, earth):
            z = y - unit.ideal(f, om, ea)
            assert _same(unit.regressor_gram(f, om, earth=ea, y=y), unit.regressor_gram(f, om, z, earth=ea))
            assert _same(
                unit.regressor_gram(f, om, earth=ea, y=y, chunk=700), unit.regressor_gram(f, om, z, earth=ea, chunk=700)
            )
    for part in (ACCELEROMETER, GyroModel()):
        y = rng.normal(size=(n, 3))
        base = part.base_regressors(f, om, earth)
        own, generic = np.empty((n, 3)), np.empty((n, 3))
        part.fill_measurement(own, y, f, om, earth, base)
        ModelSpec.fill_measurement(part, generic, y, f, om, earth, base)
        assert _same(own, generic) and _same(own, y - part.ideal(f, om, earth))
    with pytest.raises(ValueError):
        ACCELEROMETER.regressor_gram(f, om, y, y=y)


@pytest.mark.parametrize("spinning", [False, True])
def test_gram_from_the_output_as_arrays_side_by_side_is_the_gram_from_one_array(spinning: bool) -> None:
    """regressor_gram(y=(a, b, …)): the arrays whose columns side by side are the output give the Gram of their
    np.hstack, bit for bit, whether they line up with the model's parts (a unit's accelerometer and gyro outputs:
    no copy) or not (split across a part, or several arrays for a one-part model); wrong shapes are refused."""
    rng = np.random.default_rng(15)
    n = 2500
    f, om, earth = _samples(rng, n, spinning)
    unit = UnitModel((ACCELEROMETER, GyroModel()))
    y = unit.ideal(f, om, earth) + rng.normal(0.0, 1e-3, (n, 6))
    whole = unit.regressor_gram(f, om, earth=earth, y=y)
    for cut in ((3,), (1, 3), (2, 4, 5), (5,)):
        parts = tuple(np.ascontiguousarray(a) for a in np.split(y, cut, axis=1))
        assert _same(unit.regressor_gram(f, om, earth=earth, y=parts), whole), cut
        assert _same(
            unit.regressor_gram(f, om, earth=earth, y=parts, chunk=700),
            unit.regressor_gram(f, om, earth=earth, y=y, chunk=700),
        ), cut
    ya = y[:, :3].copy()
    assert _same(
        ACCELEROMETER.regressor_gram(f, om, y=(ya[:, :1].copy(), ya[:, 1:].copy())),
        ACCELEROMETER.regressor_gram(f, om, y=ya),
    )
    for bad in ((y[:, :3].copy(),), (y[:, :3].copy(), y[:-1, 3:].copy()), (y[:, :3].copy(), y[:, 3:].copy(), y)):
        with pytest.raises(ValueError, match="side by side"):
            unit.regressor_gram(f, om, earth=earth, y=bad)


def _information_per_axis(model: ModelSpec, gram: np.ndarray, r: np.ndarray) -> tuple:
    """Λ and η from a Gram axis by axis with ``np.ix_`` blocks (the plain form information_from_gram replaced)."""
    with_z = gram.shape[0] == model.gram_size(True)
    cols, zc, _ = model.layout(with_z)
    info = np.zeros((model.n_params, model.n_params))
    eta = np.zeros(model.n_params) if with_z else None
    for i in range(model.n_axes):
        p, q = list(model.axis_params[i]), list(cols[i])
        info[np.ix_(p, p)] = gram[np.ix_(q, q)] / r[i]
        if eta is not None:
            eta[p] = gram[q, zc[i]] / r[i]
    return info, eta


def test_information_from_gram_is_the_per_axis_one() -> None:
    """information_from_gram's one gather per matrix gives the per-axis ``np.ix_`` blocks' Λ and η bit for bit
    (every model, with and without z, twice: the cached indices), and a model whose axes share a state keeps
    the per-axis assignment."""
    rng = np.random.default_rng(15)
    models = [ACCELEROMETER, GyroModel(), GyroModel(full_g=True, quadratic=True, asymmetry=True)]
    models += [UnitModel((ACCELEROMETER, GyroModel())), UnitModel((ACCELEROMETER, GyroModel(quadratic=True)))]
    for model in models:
        for with_z in (False, True, True):
            m = model.gram_size(with_z)
            g = rng.normal(size=(m, m)) * 10.0 ** rng.integers(-8, 8, (m, m))
            r = rng.uniform(0.1, 10.0, model.n_axes) * 1e-6
            info, eta = model.information_from_gram(g, r)
            e_info, e_eta = _information_per_axis(model, g, r)
            assert _same(info, e_info)
            assert (eta is None) == (not with_z) and (eta is None or _same(eta, e_eta))
    shared = GyroModel()
    shared.axis_params = (shared.axis_params[0],) * 2 + shared.axis_params[2:]  # axes x and y share x's states
    g = rng.normal(size=(shared.gram_size(True),) * 2)
    r = np.array([1.0, 2.0, 3.0])
    info, eta = shared.information_from_gram(g, r)
    e_info, e_eta = _information_per_axis(shared, g, r)
    assert shared.__dict__["_info_index_cache"][(True, shared.axis_params, shared.axis_base, shared.n_base)] is None
    assert _same(info, e_info) and _same(eta, e_eta)

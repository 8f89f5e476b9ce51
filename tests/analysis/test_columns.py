"""analysis.columns: each column-wise form equals the numpy operation it replaces, bit for bit (signed zeros
included), on the shapes identification uses and on the edges (one row, one column, zeros, a reused scratch)."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from analysis.columns import column_mean, side_by_side


def _bits(a: np.ndarray) -> np.ndarray:
    return np.ascontiguousarray(a, dtype=float).view(np.int64)


def _same(a: np.ndarray, b: np.ndarray) -> bool:
    return a.shape == b.shape and np.array_equal(_bits(a), _bits(b))


@pytest.mark.parametrize("k", [1, 2, 3, 6, 9])
def test_column_mean_is_numpys_mean_bit_for_bit(k: int) -> None:
    rng = np.random.default_rng(k)
    for n in (1, 2, 3, 7, 8, 9, 16, 17, 1000, 8193, 60000):
        a = rng.normal(size=(n, k)) * 10.0 ** rng.uniform(-9, 3, k) + rng.uniform(-10, 10, k)
        assert _same(column_mean(a), a.mean(axis=0)), (n, k)


def test_column_mean_keeps_signed_zeros_and_other_layouts() -> None:
    z = np.array([[-0.0, 0.0, -0.0], [-0.0, -0.0, 0.0]])
    assert _same(column_mean(z), z.mean(axis=0))
    assert _same(column_mean(-np.zeros((50, 3))), np.zeros(3))  # all −0.0: numpy's mean is +0.0
    rng0 = np.random.default_rng(4)
    mixed = np.where(rng0.random((300, 3)) < 0.5, -0.0, 0.0)
    mixed[:, 0] = -0.0  # a column of −0.0 beside columns of other values
    mixed[:, 2] = rng0.normal(size=300)
    mixed[0, 2] = -0.0
    assert _same(column_mean(mixed), mixed.mean(axis=0))
    rng = np.random.default_rng(5)
    a = rng.normal(size=(500, 6))
    for view in (a[:, :3], a[::2], np.asfortranarray(a), a[:0]):  # not C-ordered, or empty: numpy's own
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)  # the mean of no rows
            assert _same(column_mean(view), view.mean(axis=0))


def test_column_mean_with_a_reused_scratch_array() -> None:
    """One scratch array for windows of several lengths: each mean as if alone (nothing of the previous
    window's sums leaks into the next)."""
    rng = np.random.default_rng(6)
    buf = np.full((3, 5000), np.nan)
    for n in (5000, 17, 4999, 1, 3000):
        a = rng.normal(size=(n, 3)) * 9.8
        assert _same(column_mean(a, buf), a.mean(axis=0)), n


def test_side_by_side_is_hstack() -> None:
    rng = np.random.default_rng(7)
    for n in (0, 1, 5, 60000):
        parts = [rng.normal(size=(n, 3)), rng.normal(size=(n, 3)), rng.normal(size=(n, 2))[:, ::-1]]
        parts[0][:1] = -0.0
        assert _same(side_by_side(parts), np.hstack(parts))
    with pytest.raises(ValueError):
        side_by_side([np.zeros((3, 3)), np.zeros((4, 3))])

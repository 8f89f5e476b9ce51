"""analysis.columns: side_by_side equals np.hstack bit for bit (signed zeros included); column_means equals each
column's own numpy mean bit for bit and the exact mean to rounding, on the shapes identification uses and on
the edges (one row, one column, zeros, no rows)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from analysis.columns import column_means, side_by_side


def _bits(a: np.ndarray) -> np.ndarray:
    return np.ascontiguousarray(a, dtype=float).view(np.int64)


def _same(a: np.ndarray, b: np.ndarray) -> bool:
    return a.shape == b.shape and np.array_equal(_bits(a), _bits(b))


@pytest.mark.parametrize("k", [1, 2, 3, 6, 9])
def test_column_means_are_each_columns_own_mean(k: int) -> None:
    """Each column's numpy mean (pairwise), bit for bit; within rounding of the exact mean (math.fsum) and of
    ``a.mean(axis=0)``, on the shapes identification uses, any layout."""
    rng = np.random.default_rng(k)
    for n in (1, 2, 3, 7, 8, 9, 16, 17, 1000, 8193, 60000):
        a = rng.normal(size=(n, k)) * 10.0 ** rng.uniform(-9, 3, k) + rng.uniform(-10, 10, k)
        for view in (a, np.asfortranarray(a), np.hstack([a, a])[:, ::2]):
            got = column_means(view)
            assert _same(got, np.array([view[:, j].mean() for j in range(k)])), (n, k)
            exact = np.array([math.fsum(view[:, j]) / n for j in range(k)])
            scale = np.max(np.abs(view), axis=0)
            assert np.all(np.abs(got - exact) <= 8 * np.finfo(float).eps * scale), (n, k)
            assert np.all(np.abs(got - view.mean(axis=0)) <= 4 * n * np.finfo(float).eps * scale), (n, k)


def test_column_means_of_zeros_no_rows_and_wrong_shapes() -> None:
    assert _same(column_means(-np.zeros((50, 3))), np.zeros(3))  # as numpy's mean: its sum starts from +0.0
    assert np.all(np.isnan(column_means(np.zeros((0, 3))))) and column_means(np.zeros((0, 3))).shape == (3,)
    with pytest.raises(ValueError, match="n, k"):
        column_means(np.zeros(5))


def test_side_by_side_is_hstack() -> None:
    rng = np.random.default_rng(7)
    for n in (0, 1, 5, 60000):
        parts = [rng.normal(size=(n, 3)), rng.normal(size=(n, 3)), rng.normal(size=(n, 2))[:, ::-1]]
        parts[0][:1] = -0.0
        assert _same(side_by_side(parts), np.hstack(parts))
    with pytest.raises(ValueError):
        side_by_side([np.zeros((3, 3)), np.zeros((4, 3))])

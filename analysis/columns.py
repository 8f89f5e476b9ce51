"""Column-wise forms of numpy operations on (n, k) sample arrays, faster.

numpy runs an operation over a C-ordered (n, 3) array — or into three columns of a wider row-major block —
with an inner loop three values long, once per row; for the 60 000-sample windows of an identification that
is most of the time of a mean or a copy (issue 32). :func:`side_by_side` copies column by column (the same
values bit for bit); :func:`column_means` sums each column on its own (numpy's pairwise sum: the same means to
rounding, more accurate than the row-by-row sum). Tests: tests/analysis/test_columns.py.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray


def column_means(a: NDArray[np.float64]) -> NDArray[np.float64]:
    """The mean of each column of an (n, k) float array, (k,): each column's own ``a[:, j].mean()``.

    numpy sums a column (even a strided one) pairwise, with a rounding error that grows as log n; ``a.mean(axis=0)``
    of a C-ordered array instead adds the rows one after another, a k-wide inner loop per row, with an error that
    grows as n, in about 12× the time on a 60 000 × 3 window. The two agree to rounding (a few units in the last
    place of the column's magnitude), not bit for bit. An empty array gives NaN, as numpy's mean of no rows."""
    arr = np.asarray(a, dtype=float)
    if arr.ndim != 2:
        raise ValueError(f"column_means takes an (n, k) array, got shape {arr.shape}")
    if arr.shape[0] == 0:
        return np.full(arr.shape[1], np.nan)
    return np.array([arr[:, j].mean() for j in range(arr.shape[1])])


def side_by_side(arrays: list[NDArray[np.float64]]) -> NDArray[np.float64]:
    """``np.hstack`` of (n, k_i) float arrays (the same values: a copy), column by column: (n, Σ k_i)."""
    parts = [np.asarray(a, dtype=float) for a in arrays]
    if any(p.ndim != 2 for p in parts) or len({p.shape[0] for p in parts}) > 1:
        return np.hstack(parts)  # numpy's own error for what does not fit
    out = np.empty((parts[0].shape[0] if parts else 0, sum(p.shape[1] for p in parts)))
    col = 0
    for p in parts:
        for k in range(p.shape[1]):
            out[:, col] = p[:, k]
            col += 1
    return out

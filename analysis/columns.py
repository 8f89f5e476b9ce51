"""Column-wise forms of numpy operations on (n, k) sample arrays, the same values bit for bit, faster.

numpy runs an operation over a C-ordered (n, 3) array — or into three columns of a wider row-major block —
with an inner loop three values long, once per row; for the 60 000-sample windows of an identification that
is most of the time of a mean or a copy (issue 32). These helpers do the same additions in the same order,
one column at a time. Tests: tests/analysis/test_columns.py (each against the numpy operation it replaces).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray


def column_mean(a: NDArray[np.float64], out: NDArray[np.float64] | None = None) -> NDArray[np.float64]:
    """``a.mean(axis=0)`` of a C-ordered (n, k) float array, bit for bit: (k,) (k ≥ 2; else numpy's own).

    ``mean`` over the rows of an (n, k) C-ordered array adds them one after another to 0.0 (a k-wide inner
    loop per row); the running sum of each column (``np.add.accumulate``) makes the same additions in the same
    order, one column at a time, from the first row instead of from 0.0 — the same sum except for a column of
    −0.0 only (−0.0 where numpy's is +0.0: 0.0 + (−0.0) = +0.0), hence the final + 0.0. ``out``: a (k, n)
    scratch array (overwritten), else one is allocated.
    """
    arr = np.asarray(a, dtype=float)
    if arr.ndim != 2 or arr.shape[1] < 2 or not arr.flags.c_contiguous or arr.shape[0] == 0:
        return arr.mean(axis=0)  # one column is summed pairwise, another layout maybe in another order: numpy's own
    n, k = arr.shape
    if not arr.any():  # all ±0 (a hold's body rate): numpy's sum from 0.0 is +0.0, whatever the zeros' signs
        return np.zeros(k)
    buf = np.empty((k, n)) if out is None else out[:k, :n]
    np.add.accumulate(arr, axis=0, out=buf.T)
    return (buf[:, -1] + 0.0) / n


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

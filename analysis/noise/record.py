"""The input record of :func:`analysis.noise.stability.stability`: phase (C, N) with gaps zero-filled, gap
bookkeeping for term validity, and the τ grid (:func:`m_grid`). See docs/methods/noise.md."""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

DATA_TYPES: tuple[str, ...] = ("freq", "phase")

CHUNK = 1 << 17
"""Columns per chunk of the O(N) passes."""

class Record:
    """Phase (C, N) with gaps zero-filled, plus gap bookkeeping for term validity."""

    def __init__(self, data: ArrayLike, rate: float, data_type: str) -> None:
        a = np.asarray(data)
        if a.ndim == 1:
            a = a[:, None]
        if a.ndim != 2:
            raise ValueError(f"expected a 1-D record or a 2-D array (samples × channels), got shape {a.shape}")
        if not np.issubdtype(a.dtype, np.number) or np.iscomplexobj(a):
            raise ValueError(f"expected real numeric data, got dtype {a.dtype}")
        if not (math.isfinite(rate) and rate > 0):
            raise ValueError(f"sample rate must be a positive number of Hz, got {rate}")
        if data_type not in DATA_TYPES:
            raise ValueError(f"data_type must be 'freq' or 'phase', got {data_type!r}")
        a = np.ascontiguousarray(np.asarray(a, dtype=np.float64).T)  # (C, n), a view of 1-D float64 input
        self.ts = 1.0 / rate
        self.data_type = data_type
        c, n_in = a.shape
        self.channels = c
        self.n = n_in + 1 if data_type == "freq" else n_in
        self._raw = a
        self._x: NDArray[np.float64] | None = None
        if np.isfinite(a).all():  # the usual case: one pass, no mask kept
            self.has_gaps = False
            self.gap_samples = np.zeros(c, dtype=np.int64)
            self.gap_runs = np.zeros(c, dtype=np.int64)
            self.bad_prefix = None
            self.point_ok = None
            self.freq_raw = a if data_type == "freq" else None
            return
        if np.any(np.isinf(a)):
            raise ValueError("record contains ±inf; only NaN marks a gap")
        bad = np.isnan(a)
        self.gap_samples = bad.sum(axis=1)
        self.gap_runs = (np.diff(bad.astype(np.int8), axis=1, prepend=0) == 1).sum(axis=1)
        self.has_gaps = True
        if np.all(bad, axis=1).any():
            raise ValueError("a channel holds no finite sample")
        self.bad_prefix = np.zeros((c, n_in + 1), dtype=np.int64)
        np.cumsum(bad, axis=1, out=self.bad_prefix[:, 1:])
        if data_type == "freq":  # bad intervals: prefix count over frequency samples, aligned with phase points
            self.freq_raw = a
            self.point_ok = None
        else:
            self.freq_raw = None
            self.point_ok = ~bad

    @property
    def x(self) -> NDArray[np.float64]:
        """Phase (C, N), gaps zero-filled: frequency input integrated (mean removed, x_0 = 0, chunked cumulative
        sum with carry, no full-size temporary); gap-free phase input is the caller's array itself (read only)."""
        if self._x is None:
            a = self._raw
            c, n_in = a.shape
            if self.data_type == "freq":
                mean = np.nanmean(a, axis=1, keepdims=True) if self.has_gaps else a.mean(axis=1, keepdims=True)
                x = np.empty((c, n_in + 1))
                x[:, 0] = 0.0
                carry = np.zeros((c, 1))
                step = 1 << 16
                buf = np.empty((c, min(step, n_in)))
                for s0 in range(0, n_in, step):
                    e0 = min(n_in, s0 + step)
                    blk = buf[:, : e0 - s0]
                    np.subtract(a[:, s0:e0], mean, out=blk)
                    if self.has_gaps:
                        blk[np.isnan(blk)] = 0.0
                    seg = x[:, s0 + 1 : e0 + 1]
                    np.cumsum(blk, axis=1, out=seg)
                    seg += carry
                    carry = seg[:, -1:].copy()
                    seg *= self.ts  # while in cache (the carry stays unscaled)
            elif self.has_gaps:
                x = np.where(self.point_ok, a, 0.0)
            else:
                x = a
            self._x = x
        return self._x

    @property
    def phase_formed(self) -> bool:
        """Whether the phase (:attr:`x`) has been formed or handed in already."""
        return self._x is not None

    def set_phase(self, x: NDArray[np.float64]) -> None:
        """Hand in the record's phase (C, N) formed elsewhere (the classic pass leaves it), so it is not
        integrated twice."""
        self._x = x

    def span_ok(self, start: int, count: int, span: int) -> NDArray[np.bool_] | None:
        """Validity of terms i = start … start+count−1 whose phase span is [i, i+span]; None: all valid."""
        if not self.has_gaps:
            return None
        bp = self.bad_prefix
        if self.data_type == "freq":  # frequency samples i … i+span−1 lie between phase points i and i+span
            return bp[:, start + span : start + span + count] == bp[:, start : start + count]
        return bp[:, start + span + 1 : start + span + 1 + count] == bp[:, start : start + count]

    def points_ok(self, start: int, count: int, offsets: tuple[int, ...], stride: int = 1) -> NDArray | None:
        """Validity of terms using phase points i + offsets (phase input); span validity for frequency input."""
        if not self.has_gaps:
            return None
        if self.data_type == "freq":
            ok = self.span_ok(start, count, max(offsets))
            return ok[:, ::stride]
        ok = np.ones((self.channels, len(range(start, start + count, stride))), dtype=bool)
        for o in offsets:
            ok &= self.point_ok[:, start + o : start + o + count : stride]
        return ok

    def frequency(self) -> tuple[NDArray[np.float64], NDArray[np.int64] | None]:
        """Frequency (C, N_f) with gaps zero-filled, and the prefix count of bad frequency samples."""
        if self.data_type == "freq":
            if self.has_gaps:
                return np.where(np.isnan(self.freq_raw), 0.0, self.freq_raw), self.bad_prefix
            return self.freq_raw, None  # the caller's array: read only
        y = np.diff(self.x, axis=1) / self.ts
        if not self.has_gaps:
            return y, None
        bad_y = ~(self.point_ok[:, 1:] & self.point_ok[:, :-1])
        y[bad_y] = 0.0
        bp = np.zeros((y.shape[0], y.shape[1] + 1), dtype=np.int64)
        np.cumsum(bad_y, axis=1, out=bp[:, 1:])
        return y, bp


# ------------------------------------------------------------------------------------------------ τ grid


def m_grid(n_points: int, taus: str | ArrayLike, rate: float) -> NDArray[np.int64]:
    """Candidate averaging factors for a record of ``n_points`` phase points (each estimator keeps its range).

    ``octave``: 1, 2, 4, …; ``decade``: 1, 2, 4, 10, 20, 40, … (Stable32's spacing); ``all``: every m;
    an array: τ in seconds, rounded to the nearest m (as allantools).
    """
    top = max(int(n_points) - 1, 1)
    if isinstance(taus, str):
        kind = taus.lower()
        if kind == "octave":
            m = 2 ** np.arange(int(math.floor(math.log2(top))) + 1, dtype=np.int64)
        elif kind == "decade":
            k = int(math.floor(math.log10(top))) + 1
            m = np.array([f * 10**e for e in range(k) for f in (1, 2, 4)], dtype=np.int64)
        elif kind == "all":
            m = np.arange(1, top + 1, dtype=np.int64)
        elif kind == "log":
            k = int(math.floor(10 * math.log10(top))) if top > 1 else 0
            m = np.unique(np.rint(10.0 ** (np.arange(k + 1) / 10)).astype(np.int64))
        else:
            raise ValueError(f"unknown τ grid {taus!r}; use octave, decade, all, log or a list of τ in seconds")
    else:
        t = np.atleast_1d(np.asarray(taus, dtype=np.float64))
        if t.size == 0 or not np.all(np.isfinite(t)) or np.any(t <= 0):
            raise ValueError("τ values must be positive finite seconds")
        m = np.rint(t * rate).astype(np.int64)
    m = np.unique(m)
    return m[(m >= 1) & (m <= top)]



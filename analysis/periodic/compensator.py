"""Online compensation of identified periodic error terms (``docs/methods/periodic.md``).

The compensator subtracts ``Σ A_i cos(2π f_i t_j + φ_i)`` from each new sample of one channel, with
``t_j = j T_s`` counted from sample 0 of the calibration record (the phase reference of
:class:`~analysis.periodic.model.PeriodicModel`). This module imports nothing from the rest of the package: a
model is anything with ``terms`` (``frequency_hz``, ``amplitude``, ``phase_rad``) and ``rate_hz``.

Phase accuracy
--------------
The phase of every sample is computed from its *absolute* sample index, never by accumulating increments:
each term's frequency is held as a 64-bit fixed-point number of cycles per sample,
``ν_int = round(f_i / f_s · 2⁶⁴)``, and the phase in cycles is ``(ν_int · j) mod 2⁶⁴ / 2⁶⁴`` — an exact integer
product (unsigned 64-bit wrap-around is exactly "modulo one cycle"). The only approximation is the frequency
quantisation of 2⁻⁶⁴ cycles/sample (5·10⁻¹⁴ cycles after 10 h at 1 kHz), so the oscillator does not drift
however long the run.

Cost
----
- :meth:`PeriodicCompensator.process_sample`: O(number of terms) per sample (pure Python, exact integers).
- :meth:`PeriodicCompensator.process`: blocks of any length. The block is cut into chunks of ``L`` samples;
  each chunk's start phase is computed exactly from its absolute index and combined with a per-term table of
  ``cos/sin(2π ν k)``, ``k < L`` (itself exact), by the angle-addition formula; the model for all chunks is a
  single matrix product ``(chunks × 2N) @ (2N × L)``. Rounding error is ~1e-16 relative and does not grow.

Averaged data
-------------
When the unit (or the bench) outputs block averages of ``n`` raw samples, the averaged model is compensated:
the average of ``cos(2πν j + φ)`` over ``j = j₀ … j₀+n−1`` is ``D_n(ν) cos(2πν (j₀ + (n−1)/2) + φ)`` with the
Dirichlet gain ``D_n(ν) = sin(π n ν) / (n sin(π ν))`` (signed). Averaged sample ``k`` covers raw samples
``j₀ = start + k n`` onwards.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from fractions import Fraction
from typing import Protocol

import numpy as np
from numpy.typing import ArrayLike, NDArray


class _Term(Protocol):
    frequency_hz: float
    amplitude: float
    phase_rad: float


class _Model(Protocol):
    @property
    def terms(self) -> Sequence[_Term]: ...

    @property
    def rate_hz(self) -> float: ...


_TWO64 = 1 << 64
_MASK64 = _TWO64 - 1
_CYCLE_TO_RAD_64 = 2.0 * math.pi / float(_TWO64)


def frequency_to_fixed_point(frequency_hz: float, rate_hz: float) -> int:
    """Cycles per sample ``f / f_s`` as an unsigned 64-bit fixed-point integer (exact rational rounding).

    Parameters
    ----------
    frequency_hz : float
        Tone frequency, Hz (any real value; it is reduced modulo the sample rate).
    rate_hz : float
        Sample rate, Hz (> 0).

    Returns
    -------
    int
        ``round(f / f_s · 2⁶⁴) mod 2⁶⁴``.
    """
    if not (math.isfinite(frequency_hz) and math.isfinite(rate_hz)) or rate_hz <= 0:
        raise ValueError(f"frequency {frequency_hz} Hz / rate {rate_hz} Hz must be finite with a positive rate")
    nu = Fraction(frequency_hz) / Fraction(rate_hz) * _TWO64
    return round(nu) & _MASK64


def dirichlet_gain(cycles_per_sample: float | NDArray[np.float64], n: int) -> NDArray[np.float64]:
    """Signed gain of an ``n``-sample boxcar average at ``ν`` cycles per (raw) sample: sin(πnν)/(n sin(πν))."""
    nu = np.asarray(cycles_per_sample, dtype=np.float64)
    s = np.sin(np.pi * nu)
    with np.errstate(invalid="ignore", divide="ignore"):
        g = np.sin(np.pi * n * nu) / (n * s)
    # at integer ν the limit is ±1: cos(π n ν)/cos(π ν)
    near = np.abs(s) < 1e-12
    return np.where(near, np.cos(np.pi * n * nu) / np.cos(np.pi * nu), g)


class PeriodicCompensator:
    """Subtract identified periodic terms from a stream of samples of one channel (raw or block-averaged).

    Parameters
    ----------
    frequencies_hz, amplitudes, phases_rad : sequence of float
        The terms ``A_i cos(2π f_i t + φ_i)``: frequency (Hz), amplitude (channel SI unit, e.g. rad/s) and
        phase (rad) at raw sample index 0.
    rate_hz : float
        Raw sample rate, Hz.
    start_index : int
        Raw sample index (relative to the model's index 0) of the first raw sample the stream will deliver.
    decimation : int
        ``1`` for the raw stream; ``n > 1`` when each streamed value is the mean of ``n`` consecutive raw
        samples (boxcar average), in which case the averaged model is subtracted.
    chunk : int
        Table length ``L`` used by :meth:`process` (samples of the output stream).

    Notes
    -----
    The internal stream position advances with every processed sample, so ``process_sample`` and
    ``process`` may be mixed freely; :meth:`model` evaluates the model at arbitrary stream indices without
    changing the position.
    """

    def __init__(
        self,
        frequencies_hz: Sequence[float],
        amplitudes: Sequence[float],
        phases_rad: Sequence[float],
        rate_hz: float,
        start_index: int = 0,
        decimation: int = 1,
        chunk: int = 4096,
    ) -> None:
        f = [float(v) for v in frequencies_hz]
        a = [float(v) for v in amplitudes]
        p = [float(v) for v in phases_rad]
        if not (len(f) == len(a) == len(p)):
            raise ValueError("frequencies, amplitudes and phases must have the same length")
        if not all(math.isfinite(v) for v in f + a + p):
            raise ValueError("periodic terms must be finite numbers")
        if int(decimation) != decimation or decimation < 1:
            raise ValueError(f"decimation must be a positive integer, got {decimation}")
        if int(start_index) != start_index or start_index < 0:
            raise ValueError(f"start_index must be a non-negative integer, got {start_index}")
        if chunk < 1:
            raise ValueError(f"chunk must be positive, got {chunk}")
        if not math.isfinite(rate_hz) or rate_hz <= 0:
            raise ValueError(f"rate must be a positive number of Hz, got {rate_hz}")
        n = int(decimation)
        self.rate_hz = float(rate_hz)
        self.decimation = n
        self.n_terms = len(f)
        nu_int = [frequency_to_fixed_point(fi, rate_hz) for fi in f]
        # cycles per raw sample reduced to [0, 1): the same ν in the gain and the block-centring phase
        nu = np.array([float(Fraction(fi) / Fraction(rate_hz) % 1) for fi in f], dtype=np.float64)
        gain = dirichlet_gain(nu, n) if n > 1 else np.ones(len(f))
        # Per output sample k: cycles = base + step·k (mod 2^64); phase offset π ν (n−1) centres the block.
        self._step = [(v * n) & _MASK64 for v in nu_int]
        self._base = [(v * int(start_index)) & _MASK64 for v in nu_int]
        self._phase = [pi + math.pi * float(vi) * (n - 1) for pi, vi in zip(p, nu, strict=True)]
        self._amp = [ai * float(g) for ai, g in zip(a, gain, strict=True)]
        self.position = 0
        self._chunk = int(chunk)
        k = np.arange(self._chunk, dtype=np.uint64)
        table = np.empty((2 * self.n_terms, self._chunk), dtype=np.float64)
        for i, s in enumerate(self._step):
            ang = (k * np.uint64(s)).astype(np.float64) * _CYCLE_TO_RAD_64
            table[2 * i] = np.cos(ang)
            table[2 * i + 1] = np.sin(ang)
        self._table = table
        self._step_u = np.array(self._step, dtype=np.uint64)
        self._base_u = np.array(self._base, dtype=np.uint64)
        self._amp_a = np.array(self._amp, dtype=np.float64)
        self._phase_a = np.array(self._phase, dtype=np.float64)

    @classmethod
    def from_model(
        cls, model: _Model, start_index: int = 0, decimation: int = 1, chunk: int = 4096
    ) -> PeriodicCompensator:
        """A compensator for an identified model (``terms`` and ``rate_hz``, e.g. ``periodic.model.PeriodicModel``)."""
        return cls(
            [t.frequency_hz for t in model.terms],
            [t.amplitude for t in model.terms],
            [t.phase_rad for t in model.terms],
            model.rate_hz,
            start_index=start_index,
            decimation=decimation,
            chunk=chunk,
        )

    def reset(self, position: int = 0) -> None:
        """Move the stream position (output-sample index relative to ``start_index``)."""
        if position < 0:
            raise ValueError("position must be non-negative")
        self.position = int(position)

    def _start_phases(self, k: NDArray[np.uint64]) -> NDArray[np.float64]:
        """Phases (rad) at stream indices ``k`` (shape (m,)) → (m, terms), exact modulo 2⁶⁴ arithmetic."""
        cyc = self._base_u[None, :] + k[:, None] * self._step_u[None, :]
        return cyc.astype(np.float64) * _CYCLE_TO_RAD_64 + self._phase_a[None, :]

    def model(self, indices: ArrayLike) -> NDArray[np.float64]:
        """The periodic model at stream indices (direct evaluation, one cosine per term and sample).

        Parameters
        ----------
        indices : array_like of int
            Output-stream indices (0 = the sample at ``start_index``), non-negative.

        Returns
        -------
        ndarray
            Model values, channel SI unit.
        """
        k = np.asarray(indices)
        if k.size and (not np.issubdtype(k.dtype, np.integer) or k.min() < 0):
            raise ValueError("indices must be non-negative integers")
        if self.n_terms == 0:
            return np.zeros(k.shape)
        ph = self._start_phases(k.reshape(-1).astype(np.uint64))
        return (np.cos(ph) @ self._amp_a).reshape(k.shape)

    def model_block(self, start: int, n: int) -> NDArray[np.float64]:
        """The periodic model for ``n`` consecutive stream samples from index ``start`` (fast table path)."""
        if n <= 0:
            return np.zeros(0)
        if self.n_terms == 0:
            return np.zeros(n)
        L = self._chunk
        n_chunks = -(-n // L)
        k0 = np.uint64(start) + np.arange(n_chunks, dtype=np.uint64) * np.uint64(L)
        ph = self._start_phases(k0)  # (chunks, terms)
        w = np.empty((n_chunks, 2 * self.n_terms))
        w[:, 0::2] = self._amp_a * np.cos(ph)
        w[:, 1::2] = -self._amp_a * np.sin(ph)
        if n_chunks == 1:
            return w[0] @ self._table[:, :n]
        return (w @ self._table).reshape(-1)[:n]

    def process(self, block: ArrayLike) -> NDArray[np.float64]:
        """Compensate a block of consecutive stream samples; returns ``block − model`` and advances.

        Parameters
        ----------
        block : array_like
            1-D samples (channel SI unit) continuing the stream at the current position.
        """
        x = np.asarray(block, dtype=np.float64)
        if x.ndim != 1:
            raise ValueError(f"expected a 1-D block of samples, got shape {x.shape}")
        out = x - self.model_block(self.position, x.size)
        self.position += x.size
        return out

    def process_sample(self, value: float) -> float:
        """Compensate one sample (O(terms), exact integer phase); returns ``value − model`` and advances."""
        k = self.position
        acc = 0.0
        for a, b, s, p in zip(self._amp, self._base, self._step, self._phase, strict=True):
            cyc = (b + s * k) & _MASK64
            acc += a * math.cos(cyc * _CYCLE_TO_RAD_64 + p)
        self.position = k + 1
        return float(value) - acc


def naive_accumulated_model(
    frequencies_hz: Sequence[float],
    amplitudes: Sequence[float],
    phases_rad: Sequence[float],
    rate_hz: float,
    n: int,
) -> NDArray[np.float64]:
    """Reference *bad* oscillator: phase accumulated by float increments (drifts); for tests and benchmarks."""
    out = np.zeros(n)
    for f, a, p in zip(frequencies_hz, amplitudes, phases_rad, strict=True):
        inc = np.full(n, 2.0 * np.pi * f / rate_hz)
        inc[0] = p
        out += a * np.cos(np.cumsum(inc))
    return out

"""Synthetic noise for the noise-analysis tests (seeded; SI units)."""

from __future__ import annotations

import math

import numpy as np


def pink(n: int, rate: float, b: float, rng: np.random.Generator) -> np.ndarray:
    """Flicker rate noise with one-sided PSD S(f) = B²/(π f) (IEEE 952 bias instability B), by FFT shaping."""
    f = np.fft.rfftfreq(n, 1.0 / rate)
    s = np.zeros_like(f)
    s[1:] = b**2 / (math.pi * f[1:])
    amp = np.sqrt(s * rate * n / 2.0)
    spec = amp * (rng.normal(size=f.size) + 1j * rng.normal(size=f.size)) / math.sqrt(2.0)
    spec[0] = 0.0
    if n % 2 == 0:
        spec[-1] = spec[-1].real * math.sqrt(2.0)
    return np.fft.irfft(spec, n)

"""Discrete power-law noise (Kasdin & Walter 1992) for simulation studies of the stability estimators."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray


def kasdin_phase(alpha: int, n: int, records: int, rng: np.random.Generator) -> NDArray[np.float64]:
    """Phase records (n, records) with S_y ∝ f^α (S_x ∝ f^(α−2)) from unit white innovations, by Kasdin &
    Walter's causal filter h_k = h_{k−1}(k − 1 + b/2)/k, b = 2 − α (FFT convolution)."""
    b = 2 - alpha
    h = np.ones(n)
    for k in range(1, n):
        h[k] = h[k - 1] * (k - 1 + b / 2.0) / k
    w = rng.normal(size=(n, records))
    nfft = 2 * n
    return np.fft.irfft(np.fft.rfft(w, nfft, axis=0) * np.fft.rfft(h, nfft)[:, None], nfft, axis=0)[:n]

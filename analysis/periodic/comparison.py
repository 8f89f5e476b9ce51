"""Compensation compared with averaging and low-pass filtering on the same data (spec: the published
comparison): residual, periodic content left and bandwidth lost of each method."""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy import signal

from analysis.periodic.compensator import dirichlet_gain
from analysis.periodic.linear import design_matrix
from analysis.periodic.model import PeriodicModel

__all__ = ["welch_psd", "smoothing_comparison", "COMPARISON_UNITS"]

COMPARISON_UNITS = {
    "output_rate_hz": "Hz",
    "bandwidth_hz": "Hz",
    "bandwidth_lost": "1",
    "residual_rms": "channel",
    "periodic_rms": "channel",
}
"""Unit of each numeric field of a comparison row ("channel" = the channel's SI unit, "1" = fraction)."""


def welch_psd(x: ArrayLike, rate_hz: float, seconds: float = 4.0) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """One-sided Welch PSD (Hann, 50 % overlap, segments of ≈``seconds``), unit²/Hz, after removing the mean."""
    v = np.asarray(x, dtype=np.float64)
    nper = int(min(v.size, max(64, 1 << int(round(math.log2(max(seconds * rate_hz, 2.0)))))))
    return signal.welch(v - v.mean(), fs=rate_hz, nperseg=nper, detrend=False)


def _tone_rms(v: NDArray[np.float64], freqs: Sequence[float], times: NDArray[np.float64]) -> float:
    """RMS of the tones at ``freqs`` (aliased as the sampling demands) fitted to ``v`` sampled at ``times``."""
    if len(freqs) == 0 or v.size < 3 + 2 * len(freqs):
        return 0.0
    coef, *_ = np.linalg.lstsq(design_matrix(times, freqs), v, rcond=None)
    return float(np.sqrt(np.sum(coef[1:] ** 2) / 2.0))


def smoothing_comparison(
    x: ArrayLike,
    rate_hz: float,
    model: PeriodicModel,
    start_index: int,
    averages: Sequence[int] = (5, 10, 20),
    lowpass_order: int = 4,
) -> list[dict[str, float | str]]:
    """Compare compensation with n-sample averaging and a low-pass filter on the same data (spec).

    Parameters
    ----------
    x : array_like
        Samples after the calibration window (channel SI unit); sample 0 is raw index ``start_index``.
    rate_hz : float
        Raw sample rate, Hz.
    model : PeriodicModel
        The identified model.
    start_index : int
        Raw index of ``x[0]`` relative to the model's phase reference.
    averages : sequence of int
        Block-average lengths.
    lowpass_order : int
        Order of the causal Butterworth low-pass, cut at half the lowest identified tone frequency (so every
        tone is attenuated; f_s/4 when there is none).

    Returns
    -------
    list of dict
        One row per method: ``method``, ``output_rate_hz`` (Hz), ``bandwidth_hz`` (−3 dB, capped at the output
        Nyquist, Hz), ``bandwidth_lost`` (fraction of the raw Nyquist band), ``residual_rms`` (about the offset,
        channel SI unit) and ``periodic_rms`` (RMS of the tones still present, fitted at the identified
        frequencies, channel SI unit) — units in :data:`COMPARISON_UNITS`.
    """
    v = np.asarray(x, dtype=np.float64) - model.offset
    n = v.size
    freqs = [tm.frequency_hz for tm in model.terms]
    t = (start_index + np.arange(n)) / rate_hz
    nyq = rate_hz / 2.0
    rows: list[dict[str, float | str]] = []

    def row(method: str, out_rate: float, bw: float, data: NDArray, times: NDArray) -> None:
        rows.append(
            {
                "method": method,
                "output_rate_hz": out_rate,
                "bandwidth_hz": bw,
                "bandwidth_lost": max(0.0, 1.0 - bw / nyq),
                "residual_rms": float(np.sqrt(np.mean(data**2))) if data.size else math.nan,
                "periodic_rms": _tone_rms(data, freqs, times),
            }
        )

    row("none", rate_hz, nyq, v, t)
    comp = model.compensator(start_index=start_index)
    row("compensation", rate_hz, nyq, comp.process(v), t)
    for m in averages:
        nb = n // m
        if nb < 4:
            continue
        avg = v[: nb * m].reshape(nb, m).mean(axis=1)
        tc = t[: nb * m].reshape(nb, m).mean(axis=1)
        # −3 dB point of the m-sample boxcar, capped at the output Nyquist frequency
        fgrid = np.linspace(0.0, nyq, 20001)
        g = np.abs(dirichlet_gain(fgrid / rate_hz, m))
        f3 = float(fgrid[np.argmax(g < 1.0 / math.sqrt(2.0))])
        row(f"average {m}", rate_hz / m, min(f3, rate_hz / (2 * m)), avg, tc)
    fc = 0.5 * min(freqs) if freqs else rate_hz / 4.0
    sos = signal.butter(lowpass_order, fc, fs=rate_hz, output="sos")
    low = signal.sosfilt(sos, v - v[: min(n, 64)].mean()) + v[: min(n, 64)].mean()
    skip = min(n // 2, int(math.ceil(10.0 * rate_hz / fc)))  # drop the filter's start-up transient
    row(f"low-pass {lowpass_order}th-order Butterworth", rate_hz, fc, low[skip:], t[skip:])
    return rows

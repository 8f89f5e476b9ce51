"""Figures of a drift analysis: ACF/PACF with bands, Welch PSD, histogram with normal overlay, compensation.

Uses matplotlib's object API (no pyplot global state) with the Agg canvas, so it is safe in tests and
threads. Values are plotted in the channel's SI unit (label given by the caller). Pure: the figures are
returned; the command (``benches/cli/commands/drift.py``) writes them as PNG files.
"""

from __future__ import annotations

import math

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from scipy import signal, stats

from analysis.drift.report import ChannelDrift


def _finish(fig: Figure) -> Figure:
    FigureCanvasAgg(fig)
    fig.tight_layout()
    return fig


def plot_channel(result: ChannelDrift, name: str, unit: str) -> dict[str, Figure]:
    """Figures of one channel, keyed ``acf``, ``psd``, ``hist``, ``compensation`` (Agg canvases attached)."""
    s = result.summary
    rate = float(s["rate_hz"])
    figures: dict[str, Figure] = {}

    fig = Figure(figsize=(9, 6))
    for i, (vals, band, title) in enumerate(
        ((result.acf, result.acf_band, "ACF (Bartlett band)"), (result.pacf, None, "PACF (±z/√n band)"))
    ):
        ax = fig.add_subplot(2, 1, i + 1)
        lags = np.arange(vals.size)
        ax.vlines(lags, 0, vals, color="C0")
        ax.plot(lags, vals, "o", ms=3, color="C0")
        if band is not None:
            ax.fill_between(lags, -band, band, color="C1", alpha=0.25)
        else:
            ax.axhspan(-result.pacf_band, result.pacf_band, color="C1", alpha=0.25)
        ax.axhline(0, color="k", lw=0.5)
        ax.set_title(f"{name}: {title}")
        ax.set_xlabel("lag (samples)")
    figures["acf"] = _finish(fig)

    fig = Figure(figsize=(9, 4.5))
    ax = fig.add_subplot(1, 1, 1)
    y = result.residual
    nper = int(s["tests"]["welch_periodicity"]["extra"]["nperseg"])
    f, p = signal.welch(y - y.mean(), fs=rate, nperseg=min(nper, y.size))
    ax.loglog(f[1:], p[1:], lw=0.8, label="Welch PSD (detrended)")
    m = s["model"]
    if m["p"] + m["q"] > 0:
        w = 2 * np.pi * f[1:] / rate
        z = np.exp(-1j * w)
        num = np.abs(1 - sum(t * z ** (j + 1) for j, t in enumerate(m["theta"]))) ** 2
        den = np.abs(1 - sum(ph * z ** (j + 1) for j, ph in enumerate(m["phi"]))) ** 2
        ax.loglog(f[1:], 2 * m["sigma2"] / rate * num / den, "C3", lw=1.2, label=f"ARMA({m['p']},{m['q']}) model")
    for ft in s["tones_hz"]:
        ax.axvline(ft, color="C2", ls=":", lw=1)
    ax.set_xlabel("frequency (Hz)")
    ax.set_ylabel(f"PSD ({unit})²/Hz")
    ax.set_title(f"{name}: power spectral density (dotted: tones for 'tablebench periodic')")
    ax.legend()
    figures["psd"] = _finish(fig)

    fig = Figure(figsize=(7, 4.5))
    ax = fig.add_subplot(1, 1, 1)
    mu, sd = float(np.mean(y)), float(np.std(y))
    ax.hist(y, bins=80, density=True, alpha=0.6, label="detrended record")
    xs = np.linspace(mu - 5 * sd, mu + 5 * sd, 400)
    ax.plot(xs, stats.norm.pdf(xs, mu, sd), "C3", label="normal, same mean and σ")
    jb = s["tests"]["jarque_bera"]
    ax.set_title(f"{name}: histogram; JB = {jb['statistic']:.3g} (threshold {jb['threshold']:.3g}, {jb['verdict']})")
    ax.set_xlabel(unit)
    ax.legend()
    figures["hist"] = _finish(fig)

    fig = Figure(figsize=(9, 4.5))
    ax = fig.add_subplot(1, 1, 1)
    ns = result.compensated.size
    if ns:
        t = np.arange(ns) / rate
        ax.plot(t, result.residual[:ns] - s["model"]["mean"], lw=0.5, label="before (detrended)")
        ax.plot(t, result.compensated, lw=0.5, label="after (minus smoothed ARMA drift)")
        ax.plot(t, result.smoothed_drift, lw=0.8, label="smoothed drift")
        ax.legend()
    else:
        ax.text(0.5, 0.5, "white residual: nothing to compensate", ha="center", transform=ax.transAxes)
    ax.set_title(compensation_title(name, s["compensation"], unit))
    ax.set_xlabel("time (s)")
    ax.set_ylabel(unit)
    figures["compensation"] = _finish(fig)
    return figures


def compensation_title(name: str, comp: dict, unit: str) -> str:
    """Title of the compensation plot: σ before and, only when it was computed (p > 0), after the Kalman filter."""
    parts = [f"{name}: drift compensation, σ before {comp['std_before']:.3g} {unit}"]
    after = comp.get("std_after_filter")
    if after is not None and math.isfinite(after):
        parts.append(f"after filter {after:.3g} {unit}")
    else:
        parts.append("nothing predictable to remove (white residual)")
    return ", ".join(parts)

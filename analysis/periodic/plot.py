"""Plot of the periodic error analysis: PSD before/after compensation and the comparison with smoothing.

Returns a matplotlib :class:`~matplotlib.figure.Figure` (no file is written here; the command saves it). Takes
arrays in SI and a display scale (SI value of one display unit) for the axis labels.
"""

from __future__ import annotations

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from analysis.periodic.comparison import welch_psd
from analysis.periodic.report import ChannelAnalysis

__all__ = ["plot_channel"]


def plot_channel(
    result: ChannelAnalysis,
    rate_hz: float,
    channel: str,
    unit_label: str = "SI",
    unit_si: float = 1.0,
) -> Figure:
    """Welch PSD before/after compensation (tones marked) and the residual-vs-bandwidth comparison.

    Parameters
    ----------
    result : ChannelAnalysis
        The channel's analysis.
    rate_hz : float
        Sample rate, Hz.
    channel : str
        Channel name for the title.
    unit_label, unit_si : str, float
        Display unit and the SI value of one display unit (e.g. "deg/s", π/180).

    Returns
    -------
    Figure
        With an Agg canvas attached (``fig.savefig`` works without pyplot).
    """
    fb, pb = welch_psd(result.before, rate_hz)
    _, pa = welch_psd(result.after, rate_hz)
    scale = 1.0 / unit_si**2
    fig = Figure(figsize=(9, 8))
    FigureCanvasAgg(fig)
    ax, ax2 = fig.subplots(2, 1, gridspec_kw={"height_ratios": [3, 2]})
    ax.semilogy(fb[1:], pb[1:] * scale, lw=0.8, label="before compensation")
    ax.semilogy(fb[1:], pa[1:] * scale, lw=0.8, label="after compensation")
    for term in result.model.terms:
        ax.axvline(term.frequency_hz, color="0.6", lw=0.6, ls=":")
    ax.set_xlabel("frequency (Hz)")
    ax.set_ylabel(f"PSD ({unit_label})²/Hz")
    ax.set_title(f"{channel}: periodic error compensation (calibrated on {result.calibration_samples / rate_hz:g} s)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(loc="upper right")
    rows = result.comparison
    names = [str(r["method"]) for r in rows]
    resid = np.array([float(r["residual_rms"]) for r in rows]) / unit_si
    bw = np.array([float(r["bandwidth_hz"]) for r in rows])
    y = np.arange(len(rows))
    ax2.barh(y, resid, color="C0", alpha=0.7, label=f"residual RMS ({unit_label})")
    ax2.set_yticks(y, names)
    ax2.invert_yaxis()
    ax2.set_xlabel(f"residual RMS ({unit_label})")
    for yi, r, b in zip(y, resid, bw, strict=True):
        ax2.text(r, yi, f"  {r:.3g} {unit_label}, bandwidth {b:.3g} Hz", va="center", fontsize=8)
    ax2.set_xlim(0, resid.max() * 1.9 if resid.size and resid.max() > 0 else 1)
    ax2.grid(True, axis="x", alpha=0.3)
    fig.tight_layout()
    return fig

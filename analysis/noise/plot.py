"""Log-log Allan-deviation figure of a noise analysis (for ``tablebench noise`` and the certificate).

Plots, per channel, the overlapping Allan deviation with its χ² confidence band, the total deviation, the
fitted noise model and each fitted term's line. Gyro channels are shown in °/h, accelerometer channels in µg
(conversions from :mod:`analysis.units`); other data in its own SI unit. Only matplotlib (Agg), no display.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from analysis import units
from analysis.noise.terms import TERMS, noise_model, term_contributions

_DISPLAY = {"rad/s": ("gyro_bias", "gyro"), "m/s^2": ("acceleration", "accelerometer")}
_TERM_STYLE = {"Q": "tab:purple", "N": "tab:blue", "B": "tab:green", "K": "tab:orange", "R": "tab:red"}


def _arr(values: list) -> np.ndarray:
    return np.array([np.nan if v is None else v for v in values], dtype=np.float64)


def plot_noise(result: dict, path: str | Path, title: str | None = None) -> Path:
    """Draw the noise analysis ``result`` (the :func:`analysis.noise.terms.analyse_noise` dict) to a PNG.

    Parameters
    ----------
    result : dict
        ``{"channels": {NAME: {"unit", "tau", "oadev", "totdev", "ci", "fit", "terms"}}, "confidence"}``.
    path : str or Path
        Output file (PNG).
    title : str, optional
        Figure title.

    Returns
    -------
    Path
        The written file.
    """
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    chans = result["channels"]
    names = list(chans)
    ncols = min(3, max(1, len(names)))
    nrows = math.ceil(len(names) / ncols) if names else 1
    fig, axes = plt.subplots(nrows, ncols, figsize=(4.6 * ncols, 3.6 * nrows), squeeze=False)
    conf = float(result.get("confidence", 0.683))
    for k, name in enumerate(names):
        ax = axes[k // ncols][k % ncols]
        ch = chans[name]
        unit = ch.get("unit", "SI")
        kind, label = _DISPLAY.get(unit, (None, None))
        scale = 1.0 / units.DISPLAY_UNITS[kind][1] if kind else 1.0
        ylab = f"Allan deviation ({units.display_unit(kind)})" if kind else f"Allan deviation ({unit})"
        tau = _arr(ch["tau"])
        oadev = _arr(ch["oadev"]) * scale
        ci = ch.get("ci", {}).get("oadev")
        if ci:
            ax.fill_between(
                tau, _arr(ci["lo"]) * scale, _arr(ci["hi"]) * scale, color="0.8", label=f"OADEV {conf:.0%} CI"
            )
        ax.loglog(tau, oadev, "o-", color="k", ms=3, lw=1, label="OADEV")
        if "totdev" in ch:
            ax.loglog(tau, _arr(ch["totdev"]) * scale, "s", mfc="none", color="tab:gray", ms=3, label="TOTDEV")
        fit = ch.get("fit")
        if fit and tau.size:
            coef = _arr(fit["coefficients"])
            tt = np.geomspace(np.nanmin(tau), np.nanmax(tau), 200)
            ax.loglog(tt, np.sqrt(noise_model(tt, coef)) * scale, "-", color="tab:red", lw=1.5, label="fit")
            contrib = term_contributions(tt, coef)
            terms = ch.get("terms_display") or ch.get("terms", {})
            for t in TERMS:
                if coef[TERMS.index(t)] > 0:
                    v = terms.get(t, {}).get("value")
                    lab = f"{t} = {v:.3g} {terms[t]['unit']}" if v is not None else t
                    ax.loglog(tt, contrib[t] * scale, ":", color=_TERM_STYLE[t], lw=1, label=lab)
        finite = oadev[np.isfinite(oadev) & (oadev > 0)]
        if finite.size:
            ax.set_ylim(finite.min() / 4.0, finite.max() * 3.0)
        ax.set_title(f"{name} ({label})" if label else name, fontsize=9)
        ax.set_xlabel("τ (s)")
        ax.set_ylabel(ylab, fontsize=8)
        ax.grid(True, which="major", lw=0.4)
        ax.grid(True, which="minor", lw=0.2, alpha=0.4)
        ax.legend(fontsize=6, loc="best")
    for k in range(len(names), nrows * ncols):
        axes[k // ncols][k % ncols].set_visible(False)
    if title:
        fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    out = Path(path)
    fig.savefig(out, dpi=110)
    plt.close(fig)
    return out

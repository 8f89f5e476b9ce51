"""Log-log stability figure of a noise analysis (for ``tablebench noise`` and the certificate).

Per channel: every chosen deviation with its χ² confidence interval (error bars at the printed confidence),
the fitted noise model and each fitted term's line; the phase-unit statistics (TDEV, TTOTDEV, MTIE, TIE rms)
on a second row. Gyro channels in deg/h, accelerometer channels in µg (display units of
:mod:`analysis.units`, as every other command), other data in its own unit. Returns a matplotlib Figure (Agg);
the caller writes it.
"""

from __future__ import annotations

import math

import numpy as np

from analysis import units
from analysis.noise.terms import TERMS, noise_model, term_contributions

_DISPLAY = {"rad/s": ("gyro_bias", "gyro"), "m/s^2": ("acceleration", "accelerometer")}
_PHASE_UNIT = ("tdev", "ttotdev", "mtie", "tierms")
_TERM_STYLE = {"Q": "tab:purple", "N": "tab:blue", "B": "tab:green", "K": "tab:orange", "R": "tab:red"}
_MARKERS = "osD^v<>phX*"


def _arr(values) -> np.ndarray:
    return np.array([np.nan if v is None else v for v in np.ravel(values)], dtype=np.float64)


def plot_noise(result: dict, title: str | None = None):
    """Figure of the :func:`analysis.noise.terms.analyse_noise` result (one column per channel).

    Parameters
    ----------
    result : dict
        ``{"channels": {NAME: {"unit", "deviations": {EST: {"tau", "value", "lo", "hi"}}, "fit", "terms…"}},
        "confidence"}``.
    title : str, optional
        Figure title.

    Returns
    -------
    matplotlib.figure.Figure
    """
    import matplotlib

    matplotlib.use("Agg", force=False)
    from matplotlib.figure import Figure

    chans = result["channels"]
    names = list(chans)
    ncols = max(1, len(names))
    any_phase = any(e in _PHASE_UNIT for ch in chans.values() for e in ch.get("deviations", {}))
    nrows = 2 if any_phase else 1
    fig = Figure(figsize=(4.8 * min(ncols, 3), 3.8 * nrows * math.ceil(ncols / 3)))
    grid = fig.subplots(nrows * math.ceil(ncols / 3), min(ncols, 3), squeeze=False)
    conf = float(result.get("confidence", 0.683))
    for k, name in enumerate(names):
        row0 = (k // 3) * nrows
        ax = grid[row0][k % 3]
        ch = chans[name]
        unit = ch.get("unit", "SI")
        kind, label = _DISPLAY.get(unit, (None, None))
        scale = 1.0 / units.DISPLAY_UNITS[kind][1] if kind else 1.0
        ulabel = units.display_unit(kind) if kind else unit
        finite_all = []
        for i, (est, d) in enumerate(ch.get("deviations", {}).items()):
            if est in _PHASE_UNIT:
                continue
            tau = _arr(d["tau"])
            val = _arr(d.get("value_unbiased", d["value"])) * scale
            if "lo" in d:
                lo = _arr(d["lo"]) * scale
                hi = _arr(d["hi"]) * scale
                err = np.vstack([np.clip(val - lo, 0, None), np.clip(hi - val, 0, None)])
                err = np.where(np.isfinite(err), err, 0.0)
                ax.errorbar(tau, val, yerr=err, fmt=_MARKERS[i % len(_MARKERS)] + "-", ms=3, lw=0.8, capsize=2,
                            label=est.upper())
            else:
                ax.loglog(tau, val, _MARKERS[i % len(_MARKERS)] + "-", ms=3, lw=0.8, label=est.upper())
            finite_all.append(val[np.isfinite(val) & (val > 0)])
        fit = ch.get("fit")
        tau_fit = _arr(ch.get("tau", []))
        if fit and tau_fit.size:
            coef = _arr(fit["coefficients"])
            tt = np.geomspace(np.nanmin(tau_fit), np.nanmax(tau_fit), 200)
            ax.plot(tt, np.sqrt(noise_model(tt, coef)) * scale, "-", color="tab:red", lw=1.5,
                    label=f"fit ({fit.get('estimator', '')})")
            contrib = term_contributions(tt, coef)
            terms = ch.get("terms_display") or ch.get("terms", {})
            for t in TERMS:
                if coef[TERMS.index(t)] > 0:
                    v = terms.get(t, {}).get("value")
                    lab = f"{t} = {v:.3g} {terms[t]['unit']}" if v is not None else t
                    ax.plot(tt, contrib[t] * scale, ":", color=_TERM_STYLE[t], lw=1, label=lab)
        ax.set_xscale("log")
        ax.set_yscale("log")
        vals = np.concatenate(finite_all) if finite_all else np.zeros(0)
        if vals.size:
            ax.set_ylim(vals.min() / 4.0, vals.max() * 3.0)
        ax.set_title(f"{name} ({label})" if label else name, fontsize=9)
        ax.set_xlabel("τ (s)")
        ax.set_ylabel(f"deviation ({ulabel}); bars: {conf:.1%} CI", fontsize=8)
        ax.grid(True, which="major", lw=0.4)
        ax.grid(True, which="minor", lw=0.2, alpha=0.4)
        ax.legend(fontsize=6, loc="best")
        if any_phase:
            axp = grid[row0 + 1][k % 3]
            for i, (est, d) in enumerate(ch.get("deviations", {}).items()):
                if est not in _PHASE_UNIT:
                    continue
                tau = _arr(d["tau"])
                val = _arr(d["value"])
                if "lo" in d:
                    err = np.vstack([np.clip(val - _arr(d["lo"]), 0, None), np.clip(_arr(d["hi"]) - val, 0, None)])
                    axp.errorbar(tau, val, yerr=np.where(np.isfinite(err), err, 0.0), fmt=_MARKERS[i % 10] + "-",
                                 ms=3, lw=0.8, capsize=2, label=est.upper())
                else:
                    axp.plot(tau, val, _MARKERS[i % 10] + "-", ms=3, lw=0.8, label=est.upper())
            axp.set_xscale("log")
            axp.set_yscale("log")
            axp.set_xlabel("τ (s)")
            axp.set_ylabel("time-domain error (phase unit, SI)", fontsize=8)
            axp.grid(True, which="major", lw=0.4)
            axp.legend(fontsize=6, loc="best")
    for r in range(grid.shape[0]):
        for c in range(grid.shape[1]):
            if not grid[r][c].has_data():
                grid[r][c].set_visible(False)
    if title:
        fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    return fig


def plot_dynamic(dyn: dict[str, dict], title: str | None = None):
    """Dynamic Allan deviation picture: per channel, time along the record (x) against τ (y, log), colour the
    deviation (log scale); ``dyn`` maps channel → :func:`analysis.noise.dynamic.dynamic_adev` result."""
    import matplotlib

    matplotlib.use("Agg", force=False)
    from matplotlib.colors import LogNorm
    from matplotlib.figure import Figure

    names = list(dyn)
    fig = Figure(figsize=(6.0, 3.2 * len(names)))
    axes = fig.subplots(len(names), 1, squeeze=False)[:, 0]
    for ax, name in zip(axes, names, strict=True):
        d = dyn[name]
        v = np.asarray(d["adev"], dtype=np.float64)
        ok = np.isfinite(v) & (v > 0)
        norm = LogNorm(vmin=float(v[ok].min()), vmax=float(v[ok].max())) if ok.any() else None
        t, tau = np.asarray(d["t_centre"]), np.asarray(d["tau"])
        mesh = ax.pcolormesh(t, tau, np.where(ok, v, np.nan).T, shading="nearest", norm=norm, cmap="viridis")
        ax.set_yscale("log")
        ax.set_xlabel("time along the record (window centre), s")
        ax.set_ylabel("τ, s")
        ax.set_title(f"{name}: overlapping ADEV per window")
        fig.colorbar(mesh, ax=ax, label="ADEV (SI rate unit)")
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    return fig


def plot_psd(psds: dict[str, dict], allan_terms: dict[str, dict], ts: float, title: str | None = None):
    """One-sided rate PSD per channel (Welch and its log bins) with the noise terms drawn in the frequency domain:
    the PSD fit's terms (solid) and the Allan fit's terms (dashed), IEEE 952 forms
    (:func:`analysis.noise.psd.term_psd`)."""
    import matplotlib

    matplotlib.use("Agg", force=False)
    from matplotlib.figure import Figure

    from analysis.noise.psd import term_psd

    names = list(psds)
    fig = Figure(figsize=(6.0, 3.6 * len(names)))
    axes = fig.subplots(len(names), 1, squeeze=False)[:, 0]
    for ax, name in zip(axes, names, strict=True):
        p = psds[name]
        f = np.asarray(p["f"])
        ax.loglog(f, p["psd"], color="0.75", lw=0.6, label="Welch")
        ax.loglog(p["f_binned"], p["psd_binned"], "k.", ms=4, label="log bins")
        fitted = term_psd(f, {k: v[0] for k, v in p["terms"].items()}, ts)
        allan = term_psd(f, {k: d["value"] for k, d in allan_terms[name].items() if k in ("N", "B", "K")}, ts)
        for k, curve in fitted.items():
            ax.loglog(f, curve, color=_TERM_STYLE[k], lw=1.2, label=f"{k} (PSD fit)")
        for k, curve in allan.items():
            ax.loglog(f, curve, color=_TERM_STYLE[k], lw=1.0, ls="--", label=f"{k} (Allan fit)")
        ax.set_xlabel("frequency, Hz")
        ax.set_ylabel("one-sided PSD, (SI rate unit)²/Hz")
        ax.set_title(name)
        ax.legend(fontsize=6, ncol=2)
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    return fig

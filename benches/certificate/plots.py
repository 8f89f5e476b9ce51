"""Figures of the calibration certificate, as deterministic PNG bytes (matplotlib, Agg, no pyplot state).

Determinism: every figure is drawn on a bare :class:`matplotlib.figure.Figure` with the Agg canvas inside an
``rc_context`` that starts from matplotlib's defaults plus fixed overrides (so a user's matplotlibrc cannot
change the bytes), and saved without the "Software" metadata. The same inputs give the same bytes.

Display units come from :mod:`analysis.units` (µg, ppm, arcsec, µg/g², mm).
"""

from __future__ import annotations

import io
import math
from collections.abc import Mapping, Sequence
from contextlib import AbstractContextManager
from typing import Any

import matplotlib
import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.ticker import MaxNLocator
from numpy.typing import NDArray
from PIL import Image

from analysis.identification.budget import StepGeometry
from analysis.units import DEG_PER_HOUR, UG, display_unit, to_display

_RC: dict[str, Any] = {
    "font.family": "DejaVu Sans",
    "font.size": 8.0,
    "axes.titlesize": 8.5,
    "axes.labelsize": 8.0,
    "xtick.labelsize": 7.0,
    "ytick.labelsize": 7.0,
    "legend.fontsize": 7.0,
    "axes.grid": True,
    "grid.alpha": 0.35,
    "grid.linewidth": 0.5,
    "lines.linewidth": 1.0,
    "savefig.dpi": 150,
    "svg.hashsalt": "tablebench",
    "path.simplify": True,
    "figure.dpi": 100,
}
_AXIS_COLOURS = ("#1f4e9c", "#2f8f2f", "#b5332a")


def _render(fig: Figure) -> bytes:
    """PNG bytes of a figure (RGB, at ``savefig.dpi``), without timestamps or software metadata.

    Drawn once on the Agg canvas and written as an opaque RGB PNG (the figures have an opaque background):
    the PDF embeds it without splitting off an all-opaque alpha channel (issue 32); the pixels are those
    ``savefig`` would write.
    """
    dpi = float(matplotlib.rcParams["savefig.dpi"])
    canvas = FigureCanvasAgg(fig)
    fig.set_dpi(dpi)
    canvas.draw()
    rgb = np.ascontiguousarray(np.asarray(canvas.buffer_rgba())[..., :3])
    buf = io.BytesIO()
    # compress_level 1: the PNG is an intermediate (the PDF decodes it and compresses the pixels itself, so the
    # PDF is the same), and level 6 took as long as the PDF's own pass
    Image.fromarray(rgb).save(buf, format="png", dpi=(dpi, dpi), compress_level=1)
    return buf.getvalue()


def _context() -> AbstractContextManager[None]:
    """The certificate's matplotlib settings (from the defaults, so a user's matplotlibrc cannot change a figure)."""
    base = dict(matplotlib.rcParamsDefault)
    base.pop("backend", None)
    base.update(_RC)
    return matplotlib.rc_context(base)


def plot_residuals(
    per_step: Sequence[Mapping[str, Any]], noise_var: NDArray[np.float64], triad: str = "accelerometer"
) -> bytes:
    """Per-step residual mean (±2σ of the mean from the noise) and RMS per body axis (µg, or °/h for the gyro).

    Parameters
    ----------
    per_step : sequence of mapping
        ``calibration.json`` ``residuals.per_step`` rows (name, samples, mean (3 or 6), rms (3 or 6), SI, body
        frame: accelerometer m/s², then gyro rad/s).
    noise_var : (3,) array
        Measurement noise variance per body axis of the triad plotted, SI².
    triad : {"accelerometer", "gyro"}
        Which triad's columns to plot.
    """
    off_c, unit, label = (3, DEG_PER_HOUR, "°/h") if triad == "gyro" else (0, UG, "µg")
    with _context():
        fig = Figure(figsize=(7.2, 4.6))
        ax1, ax2 = fig.subplots(2, 1, sharex=True, gridspec_kw=_margins(7.2, 4.6, 2, 1, 0.75, 0.12, 0.3, 0.75, 0, 0.42))
        rows = list(per_step)
        k = np.arange(len(rows))
        n = np.array([max(float(r.get("samples", 0)), 1.0) for r in rows])
        mean = np.array([r["mean"] for r in rows], dtype=float).reshape(len(rows), -1)[:, off_c : off_c + 3] / unit
        rms = np.array([r["rms"] for r in rows], dtype=float).reshape(len(rows), -1)[:, off_c : off_c + 3] / unit
        sig = np.sqrt(np.asarray(noise_var, dtype=float))[None, :] / unit
        for a, name in enumerate("xyz"):
            off = (a - 1) * 0.22
            ax1.errorbar(
                k + off,
                mean[:, a],
                yerr=2 * sig[0, a] / np.sqrt(n),
                fmt="o",
                ms=3,
                capsize=1.5,
                color=_AXIS_COLOURS[a],
                label=f"{name}",
            )
            ax2.plot(k + off, rms[:, a], "s", ms=3, color=_AXIS_COLOURS[a], label=f"{name}")
            ax2.axhline(sig[0, a], color=_AXIS_COLOURS[a], lw=0.8, ls="--")
        ax1.axhline(0.0, color="black", lw=0.6)
        ax1.set_ylabel(f"mean residual, {label}")
        ax1.set_title(
            f"{triad.capitalize()} residuals per step (body axes); error bars: ±2σ of the mean (noise model)", y=1.0
        )
        ax1.legend(ncol=3, loc="upper right")
        ax2.set_ylabel(f"RMS residual, {label}")
        ax2.set_title("RMS per step; dashed: noise standard deviation used by the identification", y=1.0)
        ax2.set_xticks(k)
        ax2.set_xticklabels([str(r.get("name", i)) for i, r in enumerate(rows)], rotation=70, ha="right")
        return _render(fig)


CONVERGENCE_FRAME_U = 4.0
"""Half-height of a convergence panel in final standard uncertainties: the ±2σ band fills half the frame, so
the converged trace's steps are visible against it (8σ left it a flat line in a mostly empty panel)."""


def convergence_frame(values: NDArray[np.float64], sigmas: NDArray[np.float64]) -> tuple[float, float] | None:
    """The y-range of one convergence panel: the final value ± max(4 u_final, 1.2 × the second half's largest
    distance from it), display units; None when the trace is empty or not finite.

    The early, prior-dominated updates leave the frame, as they should; the late trace and its ±2u band fill it.
    """
    v = np.asarray(values, dtype=float)
    s = np.asarray(sigmas, dtype=float)
    if v.size == 0 or not np.isfinite(v[-1]):
        return None
    centre = float(v[-1])
    half = v[v.size // 2 :]
    half = half[np.isfinite(half)]
    late = float(np.max(np.abs(half - centre))) if half.size else 0.0
    u = float(s[-1]) if s.size and np.isfinite(s[-1]) else 0.0
    span = max(CONVERGENCE_FRAME_U * u, 1.2 * late)
    if not span > 0:
        span = max(abs(centre) * 1e-3, 1e-12)
    return centre - span, centre + span


def convergence_figure(
    history: Mapping[str, Any],
    names: Sequence[str],
    kinds: Sequence[str],
    final: NDArray[np.float64] | None = None,
    identified: Sequence[bool] | None = None,
) -> Figure:
    """The convergence figure of :func:`plot_convergence` (one panel per parameter, in ``names`` order)."""
    t = np.asarray(history.get("time", []), dtype=float)
    est = np.asarray(history.get("estimate", []), dtype=float).reshape(-1, len(names))
    sig = np.asarray(history.get("sigma", []), dtype=float).reshape(-1, len(names))
    tm = t / 60.0 if t.size == est.shape[0] and t.size else np.arange(est.shape[0], dtype=float)
    rows = max(1, -(-len(names) // 3))
    fig = Figure(figsize=(7.2, 1.5 * rows))
    axes = np.atleast_2d(fig.subplots(rows, 3, gridspec_kw=_grid_margins(7.2, 1.5 * rows, rows, 3)))
    span_t = (float(tm[0]), float(tm[-1])) if tm.size > 1 and tm[-1] > tm[0] else None
    for p, (name, kind) in enumerate(zip(names, kinds, strict=True)):
        ax = axes[p // 3][p % 3]
        v = to_display(kind, est[:, p]) if est.size else np.zeros(0)
        s = to_display(kind, sig[:, p]) if sig.size else np.zeros(0)
        if v.size:
            ax.fill_between(tm, v - 2 * s, v + 2 * s, step="post", color="#9db7e0", alpha=0.6, lw=0)
            ax.step(tm, v, where="post", color="#1f4e9c")
        elif not ax.has_data():
            ax.text(0.5, 0.5, "no filter history", ha="center", va="center", transform=ax.transAxes, fontsize=7)
        if final is not None and np.isfinite(final[p]):
            ax.axhline(to_display(kind, float(final[p])), color="black", lw=0.6, ls=":")
        frame = convergence_frame(v, s)
        if frame is not None:
            ax.set_ylim(*frame)
        ax.ticklabel_format(axis="y", useOffset=False)  # full values on the ticks: no offset text above the panel
        ax.xaxis.set_major_locator(MaxNLocator(4))  # at most 4 intervals a small panel: fewer ticks to lay out and
        ax.yaxis.set_major_locator(MaxNLocator(4))  # draw (a fifth of the grid's drawing time, issue 32)
        ax.set_title(f"{name} [{display_unit(kind)}]", pad=2, y=1.0)
        if identified is not None and not identified[p]:
            ax.text(0.5, 0.9, "not identified (prior only)", ha="center", va="top", transform=ax.transAxes,
                    fontsize=6.5, color="#a03000")  # fmt: skip
        if span_t is not None:
            ax.set_xlim(*span_t)  # one time axis for every panel (set, not shared: sharing costs a tick pass)
        if p + 3 < len(names):
            ax.tick_params(labelbottom=False)  # the time labels under the lowest panel of each column only
    for ax in axes.flat[len(names) :]:
        ax.set_visible(False)
    for ax in axes[-1]:
        ax.set_xlabel("bench time, min" if t.size == est.shape[0] and t.size else "update")
    fig.suptitle(
        f"Estimate after each step (band: ±2u of the filter; frame: final ± max({CONVERGENCE_FRAME_U:g}u, late "
        "spread))",
        fontsize=9,
    )
    return fig


def _grid_margins(width: float, height: float, rows: int, cols: int) -> dict[str, float]:
    """The convergence grid's margins (:func:`_margins`): small panels with titles and tick labels."""
    return _margins(width, height, rows, cols, 0.62, 0.12, 0.5, 0.42, 0.62, 0.36)


def _margins(
    width: float, height: float, rows: int, cols: int, left: float, right: float, top: float, bottom: float,
    gap_w: float, gap_h: float,
) -> dict[str, float]:  # fmt: skip
    """Fixed subplot margins, given in inches, as figure fractions (``gridspec_kw``): what ``tight_layout``
    finds for these figures, without its text-measuring pass over every axes (half of the certificate's
    plotting time, issue 32)."""
    ax_w = (width - left - right - (cols - 1) * gap_w) / cols
    ax_h = (height - top - bottom - (rows - 1) * gap_h) / rows
    return {
        "left": left / width,
        "right": 1.0 - right / width,
        "top": 1.0 - top / height,
        "bottom": bottom / height,
        "wspace": gap_w / ax_w,
        "hspace": gap_h / ax_h,
    }


def plot_convergence(
    history: Mapping[str, Any],
    names: Sequence[str],
    kinds: Sequence[str],
    final: NDArray[np.float64] | None = None,
    identified: Sequence[bool] | None = None,
) -> bytes:
    """Estimate of every parameter after each update, with ±2u bands, in display units (one panel each), PNG.

    Each panel is framed by :func:`convergence_frame` (final ± a few u), so the converged value reads against
    its own uncertainty rather than as a flat line.

    Parameters
    ----------
    history : mapping
        ``calibration.json`` ``history``: time (K,) s, estimate (K, n) SI, sigma (K, n) SI (standard, k = 1).
    names, kinds : sequence of str
        Parameter names and quantity kinds (``analysis.units.DISPLAY_UNITS`` keys).
    final : (n,) array, optional
        Final estimate (drawn as a dotted line).
    identified : sequence of bool, optional
        Per parameter; a not-identified one is labelled so in its panel (its trace is the prior's).
    """
    with _context():
        return _render(convergence_figure(history, names, kinds, final, identified))


def plot_coverage(geometry: Sequence[StepGeometry]) -> bytes:
    """Direction of the reference specific force in the body frame for every step (orientation coverage).

    Static holds are points, spins are traces; the axis markers show where ±x, ±y, ±z point up.
    Mollweide projection: longitude atan2(f_y, f_x), latitude asin(f_z/|f|), body frame.
    """
    with _context():
        fig = Figure(figsize=(7.2, 4.2))
        fig.subplots_adjust(left=0.04, right=0.96, top=0.9, bottom=0.1)
        ax = fig.add_subplot(1, 1, 1, projection="mollweide")
        holds: list[tuple[float, float]] = []
        traces: list[NDArray[np.float64]] = []  # (m, 2) lon/lat segments, one line broken by NaN rows
        for geo in geometry:
            f = np.asarray(geo.f, dtype=float)
            nrm = np.linalg.norm(f, axis=1)
            ok = nrm > 0
            if not np.any(ok):
                continue
            u = f[ok] / nrm[ok, None]
            lon = np.arctan2(u[:, 1], u[:, 0])
            lat = np.arcsin(np.clip(u[:, 2], -1, 1))
            if geo.kind == "spin":
                jumps = np.flatnonzero(np.abs(np.diff(lon)) > math.pi) + 1
                for seg_lon, seg_lat in zip(np.split(lon, jumps), np.split(lat, jumps), strict=True):
                    traces += [np.column_stack([seg_lon, seg_lat]), np.full((1, 2), np.nan)]
            else:
                holds.append((float(lon[0]), float(lat[0])))
        if traces:  # every spin as one artist (a few hundred Line2D cost more than drawing them)
            tr = np.concatenate(traces)
            ax.plot(tr[:, 0], tr[:, 1], "-", color="#b5332a", lw=1.2)
        if holds:  # the holds on top, one artist
            ax.plot([h[0] for h in holds], [h[1] for h in holds], "o", color="#1f4e9c", ms=4)
        for lbl, lon, lat in (
            ("+x up", 0.0, 0.0),
            ("+y up", math.pi / 2, 0.0),
            ("−x up", math.pi - 0.25, 0.0),
            ("−y up", -math.pi / 2, 0.0),
            ("+z up", 0.0, math.pi / 2 - 0.02),
            ("−z up", 0.0, -math.pi / 2 + 0.02),
        ):
            ax.annotate(lbl, (lon, lat), xytext=(4, 4), textcoords="offset points", fontsize=7, color="0.25")
        ax.plot([], [], "o", color="#1f4e9c", ms=4, label="static holds")
        ax.plot([], [], "-", color="#b5332a", label="constant-rate spins")
        ax.legend(loc="lower right", bbox_to_anchor=(1.0, -0.12))
        ax.set_xticklabels([])
        ax.set_title("Orientation coverage: direction of gravity (specific force) in the body frame", pad=10, y=1.0)
        return _render(fig)


__all__ = ["convergence_figure", "convergence_frame", "plot_convergence", "plot_coverage", "plot_residuals"]

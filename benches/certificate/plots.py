"""Figures of the calibration certificate, as vector drawings (:mod:`.drawing`), replayed onto the PDF page.

Residuals per step, estimate convergence and orientation coverage are drawn directly as lines, markers and text
in millimetres (no rasterising, no matplotlib: issue 32 — the Agg figures were most of the certificate's time):
the same content and styling as the earlier matplotlib figures, sharp at any zoom, their labels extractable.
Determinism: equal inputs give equal drawings (``bytes(drawing)``, whose SHA-256 certificate.json states).
What the figures show: docs/certificate.md.

The noise report's Allan deviation figure (:func:`plot_noise_report`) is drawn the same way (``tablebench
noise`` keeps its matplotlib figure, :func:`analysis.noise.plot.plot_noise`).

Display units come from :mod:`analysis.units` (µg, ppm, arcsec, µg/g², mm).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from analysis.identification.budget import StepGeometry
from analysis.units import DEG_PER_HOUR, DISPLAY_UNITS, UG, display_unit, to_display

from .drawing import BLACK, GRID, MINUS, Drawing, Panel, blend, data_limits, hex_colour, nice_ticks

_AXIS_COLOURS = tuple(hex_colour(c) for c in ("#1f4e9c", "#2f8f2f", "#b5332a"))
_BLUE, _RED = hex_colour("#1f4e9c"), hex_colour("#b5332a")
_BAND = blend(hex_colour("#9db7e0"), 0.6)
_TITLE, _LABEL, _TICK = 7.5, 7.0, 6.3
"""Font sizes, pt: panel titles, axis labels, tick labels."""


def _legend(d: Drawing, right: float, top: float, entries: Sequence[tuple[str, str, Any]], ncol: int = 1,
            size: float = 6.3, row: float = 3.6) -> None:  # fmt: skip
    """A legend box with its top right corner at (right, top): entries (label, kind "o"/"s"/"-"/"e", colour)."""
    if not entries:
        return
    col_w = 8.0 + max(len(e[0]) for e in entries) * size * 0.2  # marker, gap, about 0.57 em per character
    rows = -(-len(entries) // ncol)
    w, h = ncol * col_w + 1.5, rows * row + 1.6
    x0, y0 = right - w, top
    d.rect(x0, y0, w, h, hex_colour("#cccccc"), 0.15, fill=(255, 255, 255))
    for i, (label, kind, colour) in enumerate(entries):
        cx, cy = x0 + 1.5 + (i % ncol) * col_w, y0 + 0.8 + (i // ncol + 0.5) * row
        if kind == "-":
            d.line(cx, cy, cx + 5, cy, colour, 0.35)
        else:
            if kind == "e":
                hb = min(1.3, 0.36 * row)
                d.segments([[cx + 2.5, cy - hb, cx + 2.5, cy + hb], [cx + 2.0, cy - hb, cx + 3.0, cy - hb],
                            [cx + 2.0, cy + hb, cx + 3.0, cy + hb]], colour, 0.2)  # fmt: skip
            d.markers([[cx + 2.5, cy]], "s" if kind == "s" else "o", 1.1, colour)
        d.text(cx + 6.5, cy, label, size, align="L", valign="M")


def plot_residuals(
    per_step: Sequence[Mapping[str, Any]], noise_var: NDArray[np.float64], triad: str = "accelerometer"
) -> Drawing:
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
    rows = list(per_step)
    k = np.arange(len(rows), dtype=float)
    n = np.array([max(float(r.get("samples", 0)), 1.0) for r in rows])
    mean = np.array([r["mean"] for r in rows], dtype=float).reshape(len(rows), -1)[:, off_c : off_c + 3] / unit
    rms = np.array([r["rms"] for r in rows], dtype=float).reshape(len(rows), -1)[:, off_c : off_c + 3] / unit
    sig = np.sqrt(np.asarray(noise_var, dtype=float)) / unit
    err = 2 * sig[None, :] / np.sqrt(n)[:, None]
    d = Drawing(175.0, 112.0)
    left, width, h = 17.0, 155.0, 36.0
    xlim = (-0.6, max(len(rows) - 0.4, 0.6))
    top = Panel(d, left, 8.0, width, h, xlim, data_limits(np.concatenate([(mean - err).ravel(), (mean + err).ravel(),
                                                                           [0.0]])))  # fmt: skip
    bottom = Panel(d, left, 54.0, width, h, xlim, data_limits(np.concatenate([rms.ravel(), sig])))
    xt = (k, [str(r.get("name", i)) for i, r in enumerate(rows)])
    top.decorate((k, [""] * len(rows)), nice_ticks(*top.ylim, 7), _TICK, xlabels=False)
    bottom.decorate(xt, nice_ticks(*bottom.ylim, 5), _TICK, x_rotation=70.0)
    top.hline(0.0, BLACK, 0.2)
    for a in range(3):
        xs = top.px(k + (a - 1) * 0.22)
        lo, hi = top.py(mean[:, a] - err[:, a]), top.py(mean[:, a] + err[:, a])
        cap = 0.45
        d.segments(np.concatenate([np.column_stack([xs, lo, xs, hi]), np.column_stack([xs - cap, lo, xs + cap, lo]),
                                   np.column_stack([xs - cap, hi, xs + cap, hi])]), _AXIS_COLOURS[a], 0.2)  # fmt: skip
        d.markers(np.column_stack([xs, top.py(mean[:, a])]), "o", 1.2, _AXIS_COLOURS[a])
        bottom.hline(float(sig[a]), _AXIS_COLOURS[a], 0.25, (1.2, 0.8))
        d.markers(np.column_stack([bottom.px(k + (a - 1) * 0.22), bottom.py(rms[:, a])]), "s", 1.1, _AXIS_COLOURS[a])
    top.frame()
    bottom.frame()
    _legend(d, left + width - 1.0, 9.0, [(c, "e", _AXIS_COLOURS[i]) for i, c in enumerate("xyz")], ncol=3)
    d.text(left + width / 2, 5.5, f"{triad.capitalize()} residuals per step (body axes); error bars: ±2σ of the mean "
           "(noise model)", _TITLE, align="C")  # fmt: skip
    d.text(left + width / 2, 51.5, "RMS per step; dashed: noise standard deviation used by the identification",
           _TITLE, align="C")  # fmt: skip
    d.text(4.0, 8.0 + h / 2, f"mean residual, {label}", _LABEL, align="C", valign="T", angle=90.0)
    d.text(4.0, 54.0 + h / 2, f"RMS residual, {label}", _LABEL, align="C", valign="T", angle=90.0)
    return d


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


def _steps(t: NDArray[np.float64], v: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """A "post" step trace through (t, v): each value held until the next time (as matplotlib's step)."""
    if t.size < 2:
        return t, v
    ts = np.repeat(t, 2)[1:]
    vs = np.repeat(v, 2)[:-1]
    return ts, vs


def _conv_limits(tm: NDArray[np.float64], v: NDArray[np.float64], s: NDArray[np.float64],
                 span_t: tuple[float, float] | None) -> tuple[tuple[float, float], tuple[float, float]]:  # fmt: skip
    """One convergence panel's x and y limits (time span; :func:`convergence_frame`, else the data's range)."""
    xlim = span_t if span_t is not None else data_limits(tm, 0.0) if tm.size > 1 else (-1.0, 1.0)
    frame = convergence_frame(v, s)
    ylim = frame if frame is not None else data_limits(np.concatenate([v - 2 * s, v + 2 * s])) if v.size else (-1, 1)
    return xlim, (float(ylim[0]), float(ylim[1]))


def _conv_panel(d: Drawing, ax: Panel, tm: NDArray[np.float64], v: NDArray[np.float64], s: NDArray[np.float64],
                final: float | None, bottom: bool, identified: bool) -> None:  # fmt: skip
    """One panel of the convergence figure: the ±2u band, the grid, the estimate, the final value, labels."""
    ok = np.isfinite(v) & np.isfinite(s)
    t_ok, v_ok, s_ok = tm[ok], v[ok], s[ok]
    if v.size:
        ts, hi = _steps(t_ok, v_ok + 2 * s_ok)
        _, lo = _steps(t_ok, v_ok - 2 * s_ok)
        d.clip(ax.x, ax.y, ax.w, ax.h)
        d.polygon(np.concatenate([ax.xy(ts, hi, clamp=True), ax.xy(ts, lo, clamp=True)[::-1]]), _BAND)
        d.unclip()
    ax.decorate(nice_ticks(*ax.xlim, 4), nice_ticks(*ax.ylim, 4), _TICK, xlabels=bottom)
    d.clip(ax.x, ax.y, ax.w, ax.h)
    if v.size:
        ts, vs = _steps(t_ok, v_ok)
        d.polyline(ax.xy(ts, vs, clamp=True), _BLUE, 0.3)
    if final is not None and math.isfinite(final):
        ax.hline(final, BLACK, 0.2, (0.35, 0.6))
    d.unclip()
    if not v.size:
        d.text(ax.x + ax.w / 2, ax.y + ax.h / 2, "no filter history", 6.5, align="C", valign="M")
    if not identified:
        d.text(ax.x + ax.w / 2, ax.y + 0.1 * ax.h, "not identified (prior only)", 6.0, hex_colour("#a03000"),
               align="C", valign="T")  # fmt: skip
    d.text(ax.x + ax.w / 2, ax.y - 1.2, ax.title, _TITLE, align="C")
    ax.frame()


def convergence_figure(
    history: Mapping[str, Any],
    names: Sequence[str],
    kinds: Sequence[str],
    final: NDArray[np.float64] | None = None,
    identified: Sequence[bool] | None = None,
) -> Drawing:
    """The convergence figure of :func:`plot_convergence` (one panel per parameter, in ``names`` order; its
    ``panels`` carry each parameter's title "name [unit]" and limits)."""
    t = np.asarray(history.get("time", []), dtype=float)
    est = np.asarray(history.get("estimate", []), dtype=float).reshape(-1, len(names))
    sig = np.asarray(history.get("sigma", []), dtype=float).reshape(-1, len(names))
    timed = t.size == est.shape[0] and t.size > 0
    tm = t / 60.0 if timed else np.arange(est.shape[0], dtype=float)
    rows = max(1, -(-len(names) // 3))
    width, row_h = 165.0, 34.4
    left, top, bottom, gap_w, gap_h = 14.2, 11.5, 9.6, 14.2, 8.2
    d = Drawing(width, row_h * rows)
    pw = (width - left - 2.8 - 2 * gap_w) / 3
    ph = (d.height - top - bottom - (rows - 1) * gap_h) / rows
    span_t = (float(tm[0]), float(tm[-1])) if tm.size > 1 and tm[-1] > tm[0] else None
    for p, (name, kind) in enumerate(zip(names, kinds, strict=True)):
        v = to_display(kind, est[:, p]) if est.size else np.zeros(0)
        s = to_display(kind, sig[:, p]) if sig.size else np.zeros(0)
        xlim, ylim = _conv_limits(tm, v, s, span_t)
        ax = Panel(d, left + (p % 3) * (pw + gap_w), top + (p // 3) * (ph + gap_h), pw, ph, xlim, ylim,
                   title=f"{name} [{display_unit(kind)}]")  # fmt: skip
        fin = None if final is None else float(to_display(kind, float(final[p])))
        last = p + 3 >= len(names)
        _conv_panel(d, ax, tm, np.asarray(v, dtype=float), np.asarray(s, dtype=float), fin, last,
                    identified is None or bool(identified[p]))  # fmt: skip
        if last:
            d.text(ax.x + pw / 2, ax.y + ph + 8.3, "bench time, min" if timed else "update", _LABEL, align="C")
    d.text(width / 2, 4.5, f"Estimate after each step (band: ±2u of the filter; frame: final ± "
           f"max({CONVERGENCE_FRAME_U:g}u, late spread))", 8.0, align="C")  # fmt: skip
    return d


def plot_convergence(
    history: Mapping[str, Any],
    names: Sequence[str],
    kinds: Sequence[str],
    final: NDArray[np.float64] | None = None,
    identified: Sequence[bool] | None = None,
) -> Drawing:
    """Estimate of every parameter after each update, with ±2u bands, in display units (one panel each).

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
    return convergence_figure(history, names, kinds, final, identified)


def mollweide(lon: NDArray[np.float64], lat: NDArray[np.float64]) -> NDArray[np.float64]:
    """Mollweide projection of longitude, latitude (rad) to (x, y) with x ∈ [−2√2, 2√2], y ∈ [−√2, √2]
    (y up): 2θ + sin 2θ = π sin φ solved by Newton's method, x = 2√2/π λ cos θ, y = √2 sin θ."""
    lon, lat = np.asarray(lon, dtype=float), np.asarray(lat, dtype=float)
    target = math.pi * np.sin(lat)
    th = np.clip(lat, -math.pi / 2, math.pi / 2).copy()
    for _ in range(30):
        f = 2 * th + np.sin(2 * th) - target
        df = 2 + 2 * np.cos(2 * th)
        step = np.divide(f, df, out=np.zeros_like(f), where=df > 1e-12)
        th -= step
        if np.all(np.abs(step) < 1e-10):
            break
    th = np.clip(th, -math.pi / 2, math.pi / 2)
    return np.column_stack([2 * math.sqrt(2) / math.pi * lon * np.cos(th), math.sqrt(2) * np.sin(th)])


def _coverage_data(geometry: Sequence[StepGeometry]) -> tuple[list[tuple[float, float]], list[NDArray[np.float64]]]:
    """The holds' directions (lon, lat) and the spins' traces ((m, 2) lon/lat pieces, split where the longitude
    wraps), from each step's reference specific force in the body frame."""
    holds: list[tuple[float, float]] = []
    traces: list[NDArray[np.float64]] = []
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
            traces += [np.column_stack([a, b]) for a, b in zip(np.split(lon, jumps), np.split(lat, jumps), strict=True)]
        else:
            holds.append((float(lon[0]), float(lat[0])))
    return holds, traces


def plot_coverage(geometry: Sequence[StepGeometry]) -> Drawing:
    """Direction of the reference specific force in the body frame for every step (orientation coverage).

    Static holds are points, spins are traces; the axis markers show where ±x, ±y, ±z point up.
    Mollweide projection: longitude atan2(f_y, f_x), latitude asin(f_z/|f|), body frame; graticule every 30° of
    longitude and 15° of latitude.
    """
    d = Drawing(165.0, 96.0)
    scale, cx, cy = 150.0 / (4 * math.sqrt(2)), 82.5, 49.0

    def to_mm(lon: NDArray[np.float64], lat: NDArray[np.float64]) -> NDArray[np.float64]:
        p = mollweide(lon, lat)
        return np.column_stack([cx + scale * p[:, 0], cy - scale * p[:, 1]])

    lat_all = np.linspace(-math.pi / 2, math.pi / 2, 91)
    meridians = np.radians(np.arange(-150, 151, 30, dtype=float))
    grid = to_mm(np.repeat(meridians, lat_all.size), np.tile(lat_all, meridians.size))
    for g in np.split(grid, meridians.size):
        d.polyline(g, GRID, 0.15)
    parallels = np.radians(np.arange(-75, 76, 15, dtype=float))
    ends = to_mm(np.tile([-math.pi, math.pi], parallels.size), np.repeat(parallels, 2)).reshape(-1, 4)
    d.segments(ends, GRID, 0.15)
    for par, (x, y, _, _) in zip(range(-75, 76, 15), ends, strict=True):
        d.text(x - 1.5, y, f"{par}°".replace("-", MINUS), _TICK, hex_colour("#404040"), "R", "M")
    holds, traces = _coverage_data(geometry)
    pieces = []  # every spin, decimated to at most ~360 points and its last, one projection (NaN rows break it)
    for tr in traces:
        stride = max(1, tr.shape[0] // 360)
        keep = tr[::stride] if (tr.shape[0] - 1) % stride == 0 else np.vstack([tr[::stride], tr[-1:]])
        pieces += [keep, np.full((1, 2), np.nan)]
    if pieces:
        pts = np.concatenate(pieces)
        d.polyline(to_mm(pts[:, 0], pts[:, 1]), _RED, 0.42)
    if holds:
        h = np.array(holds)
        d.markers(to_mm(h[:, 0], h[:, 1]), "o", 1.4, _BLUE)
    for lbl, lon, lat in (("+x up", 0.0, 0.0), ("+y up", math.pi / 2, 0.0), (f"{MINUS}x up", math.pi - 0.25, 0.0),
                          (f"{MINUS}y up", -math.pi / 2, 0.0), ("+z up", 0.0, math.pi / 2 - 0.02),
                          (f"{MINUS}z up", 0.0, -math.pi / 2 + 0.02)):  # fmt: skip
        p = to_mm(np.array([lon]), np.array([lat]))[0]
        d.text(p[0] + 1.4, p[1] - 1.4, lbl, 6.5, hex_colour("#404040"))
    edge = np.concatenate([to_mm(np.full_like(lat_all, math.pi), lat_all),
                           to_mm(np.full_like(lat_all, -math.pi), lat_all)[::-1]])  # fmt: skip
    d.polyline(np.vstack([edge, edge[:1]]), BLACK, 0.25)
    _legend(d, 164.0, 86.0, [("static holds", "o", _BLUE), ("constant-rate spins", "-", _RED)])
    d.text(cx, 5.0, "Orientation coverage: direction of gravity (specific force) in the body frame", _TITLE, align="C")
    return d


_TERM_COLOURS = {t: hex_colour(c) for t, c in (("Q", "#9467bd"), ("N", "#1f77b4"), ("B", "#2ca02c"),
                                                 ("K", "#ff7f0e"), ("R", "#d62728"))}  # fmt: skip
_SUPERSCRIPT = str.maketrans("-0123456789", "⁻⁰¹²³⁴⁵⁶⁷⁸⁹")


def _decades(ax: Panel, size: float, xlabels: bool = True) -> None:
    """Log-log panel furniture: a grid at every 1–9 × 10ⁿ (decades darker), ticks and 10ⁿ labels at decades
    (the panel's limits are log10 of the data)."""
    d = ax.d
    minor, major = [], []
    for lo, hi, horizontal in ((*ax.xlim, False), (*ax.ylim, True)):
        for e in range(math.floor(lo), math.ceil(hi) + 1):
            for k in range(1, 10):
                v = e + math.log10(k)
                if lo <= v <= hi:
                    (major if k == 1 else minor).append((v, horizontal))
    for lines, colour, width in ((minor, blend(GRID, 0.5), 0.1), (major, GRID, 0.18)):
        segs = [[ax.x, float(ax.py(v)), ax.x + ax.w, float(ax.py(v))] if h else
                [float(ax.px(v)), ax.y, float(ax.px(v)), ax.y + ax.h] for v, h in lines]  # fmt: skip
        d.segments(segs, colour, width)
    for v, horizontal in major:
        label = "10" + str(round(v)).translate(_SUPERSCRIPT)
        if horizontal:
            y = float(ax.py(v))
            d.line(ax.x - 1.0, y, ax.x, y)
            d.text(ax.x - 1.6, y, label, size, align="R", valign="M")
        else:
            x = float(ax.px(v))
            d.line(x, ax.y + ax.h, x, ax.y + ax.h + 1.0)
            if xlabels:
                d.text(x, ax.y + ax.h + 1.8, label, size, align="C", valign="T")


def _noise_panel(d: Drawing, ax: Panel, ch: Mapping[str, Any], scale: float, conf: float) -> None:
    """One channel of :func:`plot_noise_report`: OADEV with its χ² interval, the fitted model and its terms."""
    from analysis.noise.terms import TERMS, noise_model, term_contributions  # lazy: scipy (--help time)

    _decades(ax, 5.6)
    legend: list[tuple[str, str, Any]] = []
    d.clip(ax.x, ax.y, ax.w, ax.h)
    for est, dev in ch.get("deviations", {}).items():
        tau = np.array([np.nan if v is None else v for v in dev["tau"]], dtype=float)
        val = np.array([np.nan if v is None else v for v in dev.get("value_unbiased", dev["value"])], dtype=float)
        ok = np.isfinite(tau) & (tau > 0) & np.isfinite(val) & (val > 0)
        x, y = np.log10(tau[ok]), np.log10(val[ok] * scale)
        if "lo" in dev and "hi" in dev:
            lo = np.array([np.nan if v is None else v for v in dev["lo"]], dtype=float)[ok] * scale
            hi = np.array([np.nan if v is None else v for v in dev["hi"]], dtype=float)[ok] * scale
            good = np.isfinite(lo) & np.isfinite(hi) & (lo > 0)
            xs, y0, y1 = ax.px(x[good]), ax.py(np.log10(lo[good]), True), ax.py(np.log10(hi[good]), True)
            d.segments(np.concatenate([np.column_stack([xs, y0, xs, y1]), np.column_stack([xs - 0.5, y0, xs + 0.5, y0]),
                                       np.column_stack([xs - 0.5, y1, xs + 0.5, y1])]), _BLUE, 0.18)  # fmt: skip
        d.polyline(ax.xy(x, y), _BLUE, 0.25)
        d.markers(ax.xy(x, y), "o", 0.9, _BLUE)
        legend.append((est.upper(), "e", _BLUE))
    fit = ch.get("fit")
    tau_fit = np.array([np.nan if v is None else v for v in np.ravel(ch.get("tau", []))], dtype=float)
    if fit and tau_fit.size:
        coef = np.asarray(fit["coefficients"], dtype=float)
        tt = np.geomspace(np.nanmin(tau_fit), np.nanmax(tau_fit), 200)
        model = np.sqrt(noise_model(tt, coef)) * scale
        d.polyline(ax.xy(np.log10(tt), np.log10(model), True), _RED, 0.4)
        legend.append((f"fit ({fit.get('estimator', '')})", "-", _RED))
        contrib, terms = term_contributions(tt, coef), ch.get("terms_display") or ch.get("terms", {})
        for t in TERMS:
            if coef[TERMS.index(t)] > 0:
                with np.errstate(divide="ignore"):
                    d.polyline(ax.xy(np.log10(tt), np.log10(contrib[t] * scale), True), _TERM_COLOURS[t], 0.25,
                               (0.4, 0.6))  # fmt: skip
                v = terms.get(t, {}).get("value")
                legend.append((f"{t} = {v:.3g} {terms[t]['unit']}" if v is not None else t, "-", _TERM_COLOURS[t]))
    d.unclip()
    ax.frame()
    _legend(d, ax.x + ax.w - 0.8, ax.y + 0.8, legend, size=5.0, row=2.6)


def plot_noise_report(noise: Mapping[str, Any], title: str = "") -> Drawing:
    """The noise report's figure: per channel (three a row), the overlapping Allan deviation with its χ²
    intervals, the fitted noise model and each fitted term's line, log-log, in display units (µg, deg/h).

    Parameters
    ----------
    noise : mapping
        The :func:`analysis.noise.terms.analyse_noise` result (``noise.json`` format) of the record's channels.
    title : str
        Shown above the panels.
    """
    chans = noise.get("channels", {})
    names = list(chans)
    rows = max(1, -(-len(names) // 3))
    d = Drawing(175.0, 8.0 + 66.0 * rows)
    pw, ph = 42.0, 48.0
    conf = float(noise.get("confidence", 0.683))
    for k, name in enumerate(names):
        ch = chans[name]
        kind, label = {"rad/s": ("gyro_bias", "gyro"), "m/s^2": ("acceleration", "accelerometer")}.get(
            ch.get("unit", ""), (None, None))  # fmt: skip
        scale = 1.0 / DISPLAY_UNITS[kind][1] if kind else 1.0
        unit = display_unit(kind) if kind else ch.get("unit", "SI")
        vals = [np.asarray([np.nan if v is None else v for v in dev.get("value_unbiased", dev["value"])], dtype=float)
                for dev in ch.get("deviations", {}).values()]  # fmt: skip
        allv = np.concatenate(vals) * scale if vals else np.zeros(0)
        allv = allv[np.isfinite(allv) & (allv > 0)]
        taus = np.concatenate([np.array([np.nan if v is None else v for v in np.ravel(dev["tau"])], dtype=float)
                               for dev in ch.get("deviations", {}).values()] or [np.ones(1)])  # fmt: skip
        taus = taus[np.isfinite(taus) & (taus > 0)]
        xlim = (math.log10(taus.min()) - 0.1, math.log10(taus.max()) + 0.1) if taus.size else (-1.0, 1.0)
        ylim = (math.log10(allv.min() / 4.0), math.log10(allv.max() * 3.0)) if allv.size else (-1.0, 1.0)
        x0, y0 = 14.0 + (k % 3) * (pw + 16.0), 14.0 + (k // 3) * 66.0
        ax = Panel(d, x0, y0, pw, ph, xlim, ylim, title=f"{name} ({label})" if label else name)
        _noise_panel(d, ax, ch, scale, conf)
        d.text(x0 + pw / 2, y0 - 1.5, ax.title, _TITLE, align="C")
        d.text(x0 + pw / 2, y0 + ph + 8.0, "τ (s)", 6.5, align="C")
        d.text(x0 - 11.0, y0 + ph / 2, f"deviation ({unit}); bars: {conf:.1%} CI", 6.0, align="C", valign="T",
               angle=90.0)  # fmt: skip
    if title:
        d.text(87.5, 5.0, title, 8.0, align="C")
    return d


__all__ = ["convergence_figure", "convergence_frame", "mollweide", "plot_convergence", "plot_coverage",
           "plot_noise_report", "plot_residuals"]

"""Vector figures of the certificate: drawing operations in millimetres, replayed onto the PDF page (issue 32).

A :class:`Drawing` records lines, polylines, filled polygons, rectangles, markers and text in the figure's own
coordinates (mm, origin at the top left, y down) and replays them with fpdf2's public drawing API
(:meth:`Drawing.draw`): the certificate's figures are vector graphics with real text (sharp at any zoom, their
labels extractable) and nothing is rasterised. Coordinates are rounded to 1 µm when recorded, and
``bytes(drawing)`` is a deterministic serialisation of the operations: the figure's identity (its SHA-256 in
certificate.json), equal for equal inputs.

:class:`Panel` maps data to a rectangle of the drawing and draws its grid, ticks, tick labels and frame;
:func:`nice_ticks` chooses at most ``nbins`` intervals of 1, 2, 2.5 or 5 × 10ⁿ (as matplotlib's MaxNLocator).
No fpdf import here: :meth:`Drawing.draw` is handed the document.
"""

from __future__ import annotations

import contextlib
import json
import math
from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

Colour = tuple[int, int, int]
BLACK: Colour = (0, 0, 0)
GRID: Colour = (222, 222, 222)
MINUS = "\u2212"
_PT = 25.4 / 72.0
"""Millimetres per point (font sizes are in points)."""


def hex_colour(spec: str) -> Colour:
    """``"#rrggbb"`` as an (r, g, b) tuple of 0–255."""
    return int(spec[1:3], 16), int(spec[3:5], 16), int(spec[5:7], 16)


def blend(colour: Colour, alpha: float) -> Colour:
    """``colour`` at opacity ``alpha`` over white, as an opaque colour (what a translucent fill on paper shows)."""
    return tuple(round(alpha * c + (1.0 - alpha) * 255) for c in colour)  # type: ignore[return-value]


def _r(v: float) -> float:
    return round(float(v), 3)


def _pts(xy: NDArray[np.float64]) -> list[list[float]]:
    return np.round(np.asarray(xy, dtype=float), 3).tolist()


class Drawing:
    """A figure as a list of drawing operations (mm, origin top left, y down); see the module docstring.

    Attributes
    ----------
    width, height : float
        Size on the page, mm (drawn at this size: font sizes are true points).
    ops : list of tuple
        The operations, in drawing order.
    panels : list of Panel
        The data panels (their titles and limits; for tests and callers that ask what a figure shows).
    """

    def __init__(self, width: float, height: float) -> None:
        self.width, self.height = float(width), float(height)
        self.ops: list[tuple[Any, ...]] = []
        self.panels: list[Panel] = []

    # ---- recording ----------------------------------------------------------------------------------------
    def segments(
        self, segs: ArrayLike, colour: Colour = BLACK, width: float = 0.2, dash: tuple[float, float] | None = None
    ) -> None:
        """Straight lines ``(x1, y1, x2, y2)`` per row, one style."""
        s = np.asarray(segs, dtype=float).reshape(-1, 4)
        s = s[np.all(np.isfinite(s), axis=1)]
        if s.size:
            self.ops.append(("seg", colour, _r(width), dash, _pts(s)))

    def line(self, x1: float, y1: float, x2: float, y2: float, colour: Colour = BLACK, width: float = 0.2,
             dash: tuple[float, float] | None = None) -> None:  # fmt: skip
        """One straight line."""
        self.segments([[x1, y1, x2, y2]], colour, width, dash)

    def polyline(
        self, xy: ArrayLike, colour: Colour = BLACK, width: float = 0.3, dash: tuple[float, float] | None = None
    ) -> None:
        """A connected line through the rows of ``xy`` (n, 2); a non-finite row breaks it."""
        p = np.asarray(xy, dtype=float).reshape(-1, 2)
        ok = np.all(np.isfinite(p), axis=1)
        breaks = np.flatnonzero(~ok)
        for run in np.split(np.arange(p.shape[0]), breaks):
            run = run[ok[run]]
            if run.size >= 2:
                self.ops.append(("poly", colour, _r(width), dash, _pts(p[run])))

    def polygon(self, xy: ArrayLike, fill: Colour) -> None:
        """A filled polygon (no outline) through the rows of ``xy`` (n, 2), finite."""
        p = np.asarray(xy, dtype=float).reshape(-1, 2)
        p = p[np.all(np.isfinite(p), axis=1)]
        if p.shape[0] >= 3:
            self.ops.append(("fill", fill, _pts(p)))

    def rect(self, x: float, y: float, w: float, h: float, colour: Colour | None = BLACK, width: float = 0.2,
             fill: Colour | None = None) -> None:  # fmt: skip
        """A rectangle: outlined (``colour``), filled (``fill``) or both."""
        self.ops.append(("rect", colour, _r(width), fill, [_r(x), _r(y), _r(w), _r(h)]))

    def markers(self, xy: ArrayLike, shape: str, size: float, colour: Colour) -> None:
        """Filled markers (``"o"`` disc, ``"s"`` square) of ``size`` mm across, centred on the rows of ``xy``."""
        p = np.asarray(xy, dtype=float).reshape(-1, 2)
        p = p[np.all(np.isfinite(p), axis=1)]
        if p.size:
            self.ops.append(("mark", shape, _r(size), colour, _pts(p)))

    def text(self, x: float, y: float, s: str, size: float = 7.0, colour: Colour = BLACK, align: str = "L",
             valign: str = "B", angle: float = 0.0, bold: bool = False) -> None:  # fmt: skip
        """Text anchored at (x, y): ``align`` L/C/R along the baseline, ``valign`` B (baseline), M (middle of
        the capitals) or T (top of the capitals), rotated ``angle`` degrees counter-clockwise about the anchor."""
        self.ops.append(("text", s, _r(size), colour, align, valign, _r(angle), bold, [_r(x), _r(y)]))

    def clip(self, x: float, y: float, w: float, h: float) -> None:
        """Clip what follows to a rectangle, until :meth:`unclip`."""
        self.ops.append(("clip", [_r(x), _r(y), _r(w), _r(h)]))

    def unclip(self) -> None:
        """End the clip of :meth:`clip`."""
        self.ops.append(("unclip",))

    def __bytes__(self) -> bytes:
        """The figure's deterministic serialisation (its identity in certificate.json)."""
        head = {"format": "tablebench vector figure 1", "size_mm": [self.width, self.height]}
        return json.dumps([head, *self.ops], ensure_ascii=False, separators=(",", ":")).encode("utf-8")

    # ---- replay -------------------------------------------------------------------------------------------
    def draw(self, pdf: Any, x0: float, y0: float, font: str) -> None:
        """Replay the operations onto ``pdf`` (an ``fpdf.FPDF`` in mm) with the figure's top left at (x0, y0),
        text in the font family ``font`` (regular and bold registered). Restores black, 0.2 mm, solid lines."""
        clips: list[Any] = []
        for op in self.ops:
            kind = op[0]
            if kind in ("seg", "poly"):
                _, colour, width, dash, pts = op
                _stroke(pdf, colour, width, dash)
                if kind == "seg":
                    for x1, y1, x2, y2 in pts:
                        pdf.line(x0 + x1, y0 + y1, x0 + x2, y0 + y2)
                else:
                    pdf.polyline([(x0 + x, y0 + y) for x, y in pts])
                if dash:
                    pdf.set_dash_pattern()
            elif kind == "fill":
                pdf.set_fill_color(*op[1])
                pdf.polygon([(x0 + x, y0 + y) for x, y in op[2]], style="F")
            elif kind == "rect":
                _, colour, width, fill, (x, y, w, h) = op
                if colour is not None:
                    _stroke(pdf, colour, width, None)
                if fill is not None:
                    pdf.set_fill_color(*fill)
                pdf.rect(x0 + x, y0 + y, w, h, style=("D" if fill is None else "DF" if colour else "F"))
            elif kind == "mark":
                _markers(pdf, op, x0, y0)
            elif kind == "text":
                _text(pdf, op, x0, y0, font)
            elif kind == "clip":
                # fpdf's own state saved with the PDF's (q … Q): colours set inside stay inside, on both sides
                x, y, w, h = op[1]
                stack = contextlib.ExitStack()
                stack.enter_context(pdf.local_context())
                stack.enter_context(pdf.rect_clip(x0 + x, y0 + y, w, h))
                clips.append(stack)
            elif kind == "unclip" and clips:
                clips.pop().close()
        while clips:
            clips.pop().close()
        pdf.set_draw_color(0, 0, 0)
        pdf.set_line_width(0.2)
        pdf.set_text_color(0, 0, 0)


def _stroke(pdf: Any, colour: Colour, width: float, dash: Sequence[float] | None) -> None:
    pdf.set_draw_color(*colour)
    pdf.set_line_width(width)
    if dash:
        pdf.set_dash_pattern(dash=dash[0], gap=dash[1])


def _markers(pdf: Any, op: tuple[Any, ...], x0: float, y0: float) -> None:
    _, shape, size, colour, pts = op
    pdf.set_fill_color(*colour)
    h = size / 2
    for x, y in pts:
        if shape == "s":
            pdf.rect(x0 + x - h, y0 + y - h, size, size, style="F")
        else:
            pdf.ellipse(x0 + x - h, y0 + y - h, size, size, style="F")


def _text(pdf: Any, op: tuple[Any, ...], x0: float, y0: float, font: str) -> None:
    _, s, size, colour, align, valign, angle, bold, (x, y) = op
    pdf.set_font(font, "B" if bold else "", size)
    pdf.set_text_color(*colour)
    dx = {"L": 0.0, "C": -0.5, "R": -1.0}[align] * pdf.get_string_width(s) if align != "L" else 0.0
    dy = {"B": 0.0, "M": 0.36, "T": 0.73}[valign] * size * _PT
    ax, ay = x0 + x, y0 + y
    if angle:
        with pdf.rotation(angle, ax, ay):
            pdf.text(ax + dx, ay + dy, s)
    else:
        pdf.text(ax + dx, ay + dy, s)


def nice_ticks(lo: float, hi: float, nbins: int = 5) -> tuple[NDArray[np.float64], list[str]]:
    """Ticks inside [lo, hi] at a step of 1, 2, 2.5 or 5 × 10ⁿ giving at most ``nbins`` intervals, and their
    labels (as many decimals as the step needs, a true minus sign)."""
    span = hi - lo
    if not (math.isfinite(span) and span > 0):
        return np.zeros(0), []
    raw = span / nbins
    mag = 10.0 ** math.floor(math.log10(raw))
    mult = next((m for m in (1.0, 2.0, 2.5, 5.0, 10.0) if m * mag >= raw * (1 - 1e-9)), 10.0)
    step = mult * mag
    first = math.ceil(lo / step - 1e-9)
    last = math.floor(hi / step + 1e-9)
    ticks = np.arange(first, last + 1, dtype=float) * step
    dec = max(0, -math.floor(math.log10(step) + 1e-9)) + (1 if mult == 2.5 else 0)
    return ticks, [tick_label(t, dec) for t in ticks]


def tick_label(v: float, decimals: int) -> str:
    """``v`` with ``decimals`` decimals and a true minus sign (no "−0")."""
    s = f"{v:.{decimals}f}"
    if float(s) == 0.0:
        s = s.lstrip("-")
    return s.replace("-", MINUS)


def data_limits(values: ArrayLike, margin: float = 0.05) -> tuple[float, float]:
    """The finite range of ``values`` widened by ``margin`` of its span each side ((−1, 1) when empty; a
    single value ± 1 % of itself, or ± 1)."""
    v = np.asarray(values, dtype=float).ravel()
    v = v[np.isfinite(v)]
    if not v.size:
        return -1.0, 1.0
    lo, hi = float(v.min()), float(v.max())
    if hi <= lo:
        pad = abs(lo) * 0.01 or 1.0
        return lo - pad, hi + pad
    pad = (hi - lo) * margin
    return lo - pad, hi + pad


class Panel:
    """A data rectangle of a :class:`Drawing`: data → mm, grid, ticks, labels, frame.

    Parameters
    ----------
    d : Drawing
    x, y, w, h : float
        The rectangle, mm in the drawing.
    xlim, ylim : (float, float)
        The data limits along x (left → right) and y (bottom → top).
    title : str
        Shown above the panel by :meth:`decorate` (kept for callers asking what the panel shows).
    """

    def __init__(self, d: Drawing, x: float, y: float, w: float, h: float, xlim: tuple[float, float],
                 ylim: tuple[float, float], title: str = "") -> None:  # fmt: skip
        self.d, self.x, self.y, self.w, self.h = d, x, y, w, h
        self.xlim, self.ylim, self.title = (float(xlim[0]), float(xlim[1])), (float(ylim[0]), float(ylim[1])), title
        d.panels.append(self)

    def px(self, v: ArrayLike) -> NDArray[np.float64]:
        """Data x → mm."""
        lo, hi = self.xlim
        return self.x + (np.asarray(v, dtype=float) - lo) / (hi - lo) * self.w

    def py(self, v: ArrayLike, clamp: bool = False) -> NDArray[np.float64]:
        """Data y → mm (``clamp``: limited to a band around the panel, for clipped lines far outside it)."""
        lo, hi = self.ylim
        out = self.y + (hi - np.asarray(v, dtype=float)) / (hi - lo) * self.h
        return np.clip(out, self.y - self.h, self.y + 2 * self.h) if clamp else out

    def xy(self, x: ArrayLike, y: ArrayLike, clamp: bool = False) -> NDArray[np.float64]:
        """(n, 2) mm points of data x, y."""
        return np.column_stack([self.px(x), self.py(y, clamp)])

    def hline(
        self, v: float, colour: Colour = BLACK, width: float = 0.2, dash: tuple[float, float] | None = None
    ) -> None:
        """A horizontal line across the panel at data y ``v`` (if inside the limits)."""
        if self.ylim[0] <= v <= self.ylim[1]:
            y = float(self.py(v))
            self.d.line(self.x, y, self.x + self.w, y, colour, width, dash)

    def decorate(self, xticks: tuple[NDArray[np.float64], list[str]] | None, yticks: tuple[NDArray[np.float64],
                 list[str]] | None, size: float = 6.0, xlabels: bool = True, x_rotation: float = 0.0,
                 grid: bool = True) -> None:  # fmt: skip
        """Grid (under the data drawn later), outward ticks and their labels (``xlabels``: x tick labels shown;
        ``x_rotation``: x tick labels rotated, ending at their tick)."""
        d, tick = self.d, 1.0
        grid_segs, tick_segs = [], []
        if xticks is not None:
            xs = self.px(xticks[0])
            keep = (xs >= self.x - 1e-6) & (xs <= self.x + self.w + 1e-6)
            for xv, lbl in zip(xs[keep], [lb for lb, k in zip(xticks[1], keep, strict=True) if k], strict=True):
                grid_segs.append([xv, self.y, xv, self.y + self.h])
                tick_segs.append([xv, self.y + self.h, xv, self.y + self.h + tick])
                if xlabels and x_rotation:
                    d.text(xv, self.y + self.h + tick + 0.8, lbl, size, align="R", valign="M", angle=x_rotation)
                elif xlabels:
                    d.text(xv, self.y + self.h + tick + 0.8, lbl, size, align="C", valign="T")
        if yticks is not None:
            ys = self.py(yticks[0])
            keep = (ys >= self.y - 1e-6) & (ys <= self.y + self.h + 1e-6)
            for yv, lbl in zip(ys[keep], [lb for lb, k in zip(yticks[1], keep, strict=True) if k], strict=True):
                grid_segs.append([self.x, yv, self.x + self.w, yv])
                tick_segs.append([self.x - tick, yv, self.x, yv])
                d.text(self.x - tick - 0.7, yv, lbl, size, align="R", valign="M")
        if grid and grid_segs:
            d.segments(grid_segs, GRID, 0.15)
        if tick_segs:
            d.segments(tick_segs, BLACK, 0.2)

    def frame(self) -> None:
        """The panel's outline (drawn last, over the data)."""
        self.d.rect(self.x, self.y, self.w, self.h, BLACK, 0.25)


__all__ = ["BLACK", "Drawing", "Panel", "blend", "data_limits", "hex_colour", "nice_ticks", "tick_label"]

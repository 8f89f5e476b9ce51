"""Figure of a run's timing residual around its motions (for a technician to see a bad link).

Top: each motion's clock offset minus the run's fitted line t₀ + ε t (µs), with its standard uncertainty
(k = 1) as error bars, against the unit's time; a bad link shows as scatter far beyond the bars, a drifting
clock as a trend. Bottom: each motion's in-fit residual expressed as time (µs): readings stamped by the host
or frames arriving in bursts raise it. Matplotlib object API with the Agg canvas (thread-safe); the figure is
returned, the caller writes it.
"""

from __future__ import annotations

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.ticker import FuncFormatter

from analysis.timebase.model import TimeBase

AXIS_NAMES = ("outer", "middle", "inner")


def _minor_label(v: float, _pos: int | None = None) -> str:
    """A log axis' minor tick label: 2 and 5 times a power of ten, plain ("0.2", "5"); the others unlabelled."""
    if not v > 0:
        return ""
    mantissa = v / 10.0 ** np.floor(np.log10(v) + 1e-9)
    return f"{v:g}" if any(abs(mantissa - m) < 1e-6 for m in (2.0, 5.0)) else ""


def plot_timing_residuals(tb: TimeBase) -> Figure:
    """The two-panel timing-residual figure of ``tb`` (see module docstring)."""
    fig = Figure(figsize=(9, 6))
    ax1 = fig.add_subplot(2, 1, 1)
    ax2 = fig.add_subplot(2, 1, 2, sharex=ax1)
    if tb.events:
        t = np.array([e.t_unit for e in tb.events])
        r = np.array([e.residual for e in tb.events]) * 1e6
        u = np.array([e.u for e in tb.events]) * 1e6
        w = np.array([e.rms_time for e in tb.events]) * 1e6
        axes = np.array([e.axis for e in tb.events])
        for a in sorted(set(axes.tolist())):
            m = axes == a
            ax1.errorbar(t[m], r[m], yerr=u[m], fmt="o", ms=4, capsize=2, label=f"{AXIS_NAMES[a]} gimbal")
            ax2.semilogy(t[m], np.maximum(w[m], 1e-3), "o", ms=4)
        ax1.axhline(0.0, color="k", lw=0.8)
        ax1.legend(loc="best", fontsize=8)
    else:
        ax1.text(0.5, 0.5, "no single-axis motion: nothing to measure the time base on", ha="center",
                 transform=ax1.transAxes)  # fmt: skip
    ax1.set_ylabel("offset − fit, µs (±u, k = 1)")
    ax1.set_title(
        f"Time base ({tb.method}): t₀ = {tb.offset * 1e3:.4f} ms ± {tb.u_offset * 1e6:.3g} µs, "
        f"ε = {tb.rate * 1e6:+.3f} ± {tb.u_rate * 1e6:.3g} ppm (u, k = 1), Birge ratio {tb.misfit:.2f}",
        fontsize=9,
    )
    if tb.events:  # plain labels (0.2, 0.5, 1, 2, 5, 10): the default 10^k labels go through mathtext, half the draw
        ax2.yaxis.set_major_formatter(FuncFormatter(lambda v, _pos: f"{v:g}"))
        ax2.yaxis.set_minor_formatter(FuncFormatter(_minor_label))
    ax2.set_ylabel("in-motion residual as time, µs")
    ax2.set_xlabel("unit time, s")
    FigureCanvasAgg(fig)
    fig.subplots_adjust(left=0.11, right=0.98, top=0.94, bottom=0.09, hspace=0.22)  # fixed: no tight_layout pass
    return fig

"""The published grid-refinement frequency search (spec step 3), kept to reproduce the paper (``method="grid"``).

One tone at a time, the others fixed, the interval D_i is split into ``M`` parts (6 ≤ M ≤ 30) and the RMS
residual e_m of a full linear refit is evaluated at the M+1 grid points (all at once, by projection on the
complement of the fixed columns). While the spread std(e_m) exceeds σ_E (relative: ``sigma_e_rel`` × the
residual RMS) *and* the grid step is above ``crb_fraction`` × the Cramér–Rao σ_f, the interval is zoomed to
[f_{m*−1}, f_{m*+1}]; a minimum on the interval edge shifts the interval (centred on that edge) instead.
Sweeps over the tones repeat until no frequency moves by more than its final grid step.

It reaches the same optimum as :mod:`~analysis.periodic.refine` (Levenberg–Marquardt, the default) but costs
several hundred linear refits; ``benchmarks/bench_periodic.py`` measures both.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from analysis.periodic.linear import design_matrix, fit_fixed_frequencies
from analysis.periodic.model import FitReport, PeriodicInputError, crb_frequency_sigma, refinement_start

__all__ = ["refine_frequencies"]


def _grid_rss(
    r0: NDArray[np.float64], q: NDArray[np.float64], t: NDArray[np.float64], grid: NDArray[np.float64]
) -> NDArray[np.float64]:
    """RSS of the full linear refit with one tone at each grid frequency, the other columns fixed (basis ``q``)."""
    # columns e^{i2π g_m t} by exact start + short recurrence over the uniform grid (≤ 31 steps, ~1e-15)
    w = 2.0 * np.pi * t
    z = np.empty((t.size, grid.size), dtype=np.complex128)
    z[:, 0] = np.exp(1j * w * grid[0])
    if grid.size > 1:
        rot = np.exp(1j * w * (grid[1] - grid[0]))
        for m in range(1, grid.size):
            np.multiply(z[:, m - 1], rot, out=z[:, m])
    cc, cs = np.ascontiguousarray(z.real), np.ascontiguousarray(z.imag)
    cc -= q @ (q.T @ cc)
    cs -= q @ (q.T @ cs)
    g11, g22, g12 = np.einsum("ij,ij->j", cc, cc), np.einsum("ij,ij->j", cs, cs), np.einsum("ij,ij->j", cc, cs)
    h1, h2 = cc.T @ r0, cs.T @ r0
    det = g11 * g22 - g12**2
    det = np.where(det > 0, det, np.inf)
    b1 = (g22 * h1 - g12 * h2) / det
    b2 = (g11 * h2 - g12 * h1) / det
    res = r0[:, None] - cc * b1 - cs * b2
    return np.einsum("ij,ij->j", res, res)


def refine_frequencies(
    x: ArrayLike,
    rate_hz: float,
    frequencies_hz: Sequence[float],
    halfwidths_hz: Sequence[float] | None = None,
    m_parts: int = 12,
    sigma_e_rel: float = 1e-10,
    crb_fraction: float = 0.05,
    max_sweeps: int = 12,
    max_zooms: int = 80,
    max_shifts: int = 20,
) -> tuple[NDArray[np.float64], FitReport]:
    """Grid-refinement fine frequency search, one tone at a time (spec step 3).

    Parameters
    ----------
    x : array_like
        1-D calibration samples (channel SI unit), sample 0 at t = 0.
    rate_hz : float
        Sample rate, Hz.
    frequencies_hz : sequence of float
        Coarse frequencies, Hz.
    halfwidths_hz : sequence of float, optional
        Half-widths of the initial intervals D_i, Hz (default 1/T).
    m_parts : int
        Number of grid parts M (6 ≤ M ≤ 30).
    sigma_e_rel : float
        σ_E relative to the residual RMS: zooming stops when std(e_m) ≤ σ_E.
    crb_fraction : float
        Zooming also stops when the grid step is below this fraction of the Cramér–Rao σ_f of the tone.
    max_sweeps, max_zooms, max_shifts : int
        Safety caps (sweeps over tones, zooms per tone search, edge shifts per tone search).

    Returns
    -------
    frequencies : ndarray
        Refined frequencies, Hz.
    report : FitReport
        ``method="grid"``; ``iterations`` counts sweeps, ``evaluations`` grid-point refits.
    """
    if not 6 <= m_parts <= 30:
        raise PeriodicInputError(f"the number of grid parts M must be between 6 and 30, got {m_parts}")
    v, freqs, half, report = refinement_start(x, rate_hz, frequencies_hz, halfwidths_hz, "grid")
    n, k = v.size, freqs.size
    if k == 0:
        return freqs, report
    t = np.arange(n) / rate_hz
    rms_scale = float(np.std(v)) or 1.0
    nyq = rate_hz / 2.0
    for sweep in range(max_sweeps):
        report.iterations = sweep + 1
        moved = False
        for i in range(k):
            others = [freqs[j] for j in range(k) if j != i]
            q, _ = np.linalg.qr(design_matrix(t, others))
            r0 = v - q @ (q.T @ v)
            # current σ̂ and A_i for the Cramér–Rao step limit
            _, amps, _, rss = fit_fixed_frequencies(v, rate_hz, freqs)
            sigma = math.sqrt(rss / max(n - (1 + 3 * k), 1))
            sf = crb_frequency_sigma(sigma, float(amps[i]), rate_hz, n)
            if sweep == 0 or not math.isfinite(sf):
                width = 2.0 * half[i]
            else:
                width = min(2.0 * half[i], max(20.0 * sf, 4.0 * report.final_step_hz[i]))
            lo, hi = freqs[i] - width / 2.0, freqs[i] + width / 2.0
            shifts = 0
            best = freqs[i]
            step = width / m_parts
            for _ in range(max_zooms):
                lo, hi = max(lo, 1e-9 * nyq), min(hi, nyq * (1 - 1e-9))
                grid = np.linspace(lo, hi, m_parts + 1)
                step = (hi - lo) / m_parts
                e = np.sqrt(np.maximum(_grid_rss(r0, q, t, grid), 0.0) / n)
                report.evaluations += grid.size
                m = int(np.argmin(e))
                best = grid[m]
                at_floor = step <= 8e-16 * max(best, 1.0)  # frequency resolution of float64: nothing finer
                if (
                    m in (0, m_parts)
                    and not at_floor
                    and shifts < max_shifts
                    and lo > 1e-9 * nyq * 1.0001
                    and hi < nyq * 0.9999
                ):
                    shifts += 1
                    lo, hi = best - (hi - lo) / 2.0, best + (hi - lo) / 2.0
                    continue
                report.edge_limited[i] = m in (0, m_parts)
                # σ_E relative to the residual, floored at 1e-12 of the data RMS (the numerical resolution of e)
                sigma_e = max(sigma_e_rel * float(e[m]), 1e-12 * rms_scale)
                if float(np.std(e)) <= sigma_e or step <= crb_fraction * sf or at_floor:
                    break
                lo, hi = grid[max(m - 1, 0)], grid[min(m + 1, m_parts)]
            if abs(best - freqs[i]) > max(step, 1.6e-14 * max(abs(best), 1.0)):
                moved = True
            freqs[i] = best
            report.final_step_hz[i] = float(step)
        if not moved:
            report.converged = True
            report.message = f"no frequency moved in sweep {sweep + 1}"
            break
    if not report.converged:
        report.message = f"frequencies still moving after {max_sweeps} sweeps"
    return freqs, report

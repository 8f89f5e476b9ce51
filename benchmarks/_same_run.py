"""Same-run, alternating timing of a method against its reference (the convention of issue 30's benchmarks).

The machine these figures come from is shared (2 cores, up to 8 engineers' jobs): absolute times swing with the
load, so every figure is a ratio of times measured back to back in one process, the two sides alternating and
the order swapped each repetition (A B, B A, A B, …), reported as the median over the repetitions with the range.
Times are the process's CPU time (``time.process_time``; one BLAS thread, so CPU time = the work of the call):
under a load of ~15 runnable jobs on 2 cores, wall-clock time stretches a 0.4 s call (shared with the other jobs
for many scheduler slices) far more than a 1 ms one (often done within one slice), which biased wall-clock ratios
towards the shorter side (Theo1: 292× by wall clock, see issue 30); CPU time is what a quiet machine's wall clock
would show.
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable

import numpy as np

THREAD_VARS = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")


def one_blas_thread() -> None:
    """Set one BLAS/OpenMP thread for everything in this process (call before numpy is imported)."""
    for var in THREAD_VARS:
        os.environ[var] = "1"


def thread_note() -> str:
    """The thread settings in force, and the process's thread count after a BLAS call (a check they hold)."""
    a = np.ones((400, 400))
    _ = a @ a
    try:
        n = len(os.listdir("/proc/self/task"))
    except OSError:
        n = -1
    settings = ", ".join(f"{v}={os.environ.get(v, 'unset')}" for v in THREAD_VARS)
    return f"{settings} for both sides (threads in the process after a 400×400 matmul: {n})"


def alternate(fns: dict[str, Callable[[], object]], reps: int) -> tuple[dict[str, list[float]], dict[str, object]]:
    """Time every callable ``reps`` times, alternating, the order reversed every other repetition.

    Returns the CPU times (s) per name, in repetition order, and each callable's last result.
    """
    times: dict[str, list[float]] = {k: [] for k in fns}
    last: dict[str, object] = {}
    names = list(fns)
    for r in range(reps):
        for k in names if r % 2 == 0 else names[::-1]:
            t0 = time.process_time()
            last[k] = fns[k]()
            times[k].append(time.process_time() - t0)
    return times, last


def ratio(times: dict[str, list[float]], ref: str, ours: str) -> tuple[float, float, float]:
    """Median, min and max over the repetitions of t_ref / t_ours (each pair timed in the same repetition)."""
    r = np.asarray(times[ref]) / np.asarray(times[ours])
    return float(np.median(r)), float(r.min()), float(r.max())


def fmt_ratio(times: dict[str, list[float]], ref: str, ours: str, digits: int = 2) -> str:
    """'**12×** (range 10–14×, 5 reps)' for t_ref / t_ours."""
    med, lo, hi = ratio(times, ref, ours)

    def f(v: float) -> str:
        return f"{v:.{digits}g}" if v < 10 ** digits else f"{v:.0f}"

    return f"**{f(med)}×** (range {f(lo)}–{f(hi)}×, {len(times[ref])} reps)"


def med_ms(ts: list[float]) -> str:
    """Median time, in ms below 1 s, else in s."""
    m = float(np.median(ts))
    return f"{m * 1e3:.3g} ms" if m < 1 else f"{m:.3g} s"


def load_note(start: tuple[float, float, float]) -> str:
    """The machine-load sentence every section carries."""
    return (
        f"Machine: {os.cpu_count()} cores shared by 8 engineers' jobs (1-min load average {start[0]:.1f} at the start, "
        f"{os.getloadavg()[0]:.1f} at the end of this run). Times are process CPU time (`time.process_time`, one "
        "BLAS thread), not wall clock: under this load the wall clock stretches long calls far more than short ones. "
        "Every ratio is same-run, the two sides timed back to back, alternating (order swapped each repetition), "
        "median over the repetitions with the range."
    )

"""Benchmark: the stability family (analysis/noise/stability.py) against allantools, ratios measured in one run.

Writes the ``noise`` section of benchmarks/RESULTS.md (issue #16):

1. MTOTDEV, HTOTDEV, TTOTDEV, Theo1 at N = 10⁴ against allantools 2024.06 on the same record and the same τ
   list. allantools' total family runs Python loops of (N − 3m)·6m iterations per τ (minutes for a full octave
   grid), so it is timed on a few averaging factors (``--small-m``) and the speed-up is the ratio of the time
   per τ on that same list; tablebench's full octave grid is timed as well. Largest relative difference of
   the deviations on the common τ.
2. ADEV, OADEV, MDEV, TOTDEV together at N = 10⁷, octave τ (m ≤ N/3), same τ list for both: allantools (no
   intervals) against tablebench's public ``stability`` call as a user runs it (noise identification, EDF and
   χ² intervals included, the default) and values only (``confidence=None``); three channels at once.
3. MTOTDEV, TTOTDEV, HTOTDEV, Theo1 at N = 10⁷, full octave grid (allantools: not attempted): time and peak
   memory.

Times: alternating repetitions (allantools, tablebench, …, order swapped each repetition) in one process, one BLAS
thread; each speed-up is the median over the repetitions of t_allantools / t_tablebench with its range; peak memory
is tracemalloc's peak during a separate call, as a multiple of the record (N × 8 bytes per channel).

    python -m benchmarks.bench_noise            # N = 10⁴ and 10⁷ (≈ 10 min on the 2-core machine)
    python -m benchmarks.bench_noise --quick    # N = 2·10³ and 10⁶, for development
"""

from __future__ import annotations

import os

os.environ.update(OPENBLAS_NUM_THREADS="1", OMP_NUM_THREADS="1", MKL_NUM_THREADS="1")  # before numpy: both sides

import argparse  # noqa: E402
import time  # noqa: E402
import tracemalloc  # noqa: E402

import numpy as np  # noqa: E402

from analysis.noise.stability import m_grid, stability  # noqa: E402
from benchmarks._results import write_section  # noqa: E402
from benchmarks._same_run import alternate, fmt_ratio, load_note, med_ms, thread_note  # noqa: E402

TOTAL = ("mtotdev", "htotdev", "ttotdev", "theo1")
CLASSIC = ("adev", "oadev", "mdev", "totdev")
RATE = 1000.0


def _record(n: int, seed: int = 1, channels: int = 1) -> np.ndarray:
    """White + random-walk rate noise plus a ramp and an offset (a gyro-like record), (n,) or (n, channels)."""
    rng = np.random.default_rng(seed)
    shape = (n, channels) if channels > 1 else (n,)
    y = rng.normal(0.0, 1e-3, shape)
    y += np.cumsum(rng.normal(0.0, 1e-7, shape), axis=0)
    ramp = 1e-9 * np.arange(n, dtype=np.float64)
    y += (ramp[:, None] if channels > 1 else ramp) + 0.2
    return y


def _time(fn) -> tuple[object, float]:
    """Result and CPU time (s) of fn() (process CPU time: see benchmarks/_same_run.py)."""
    t0 = time.process_time()
    out = fn()
    return out, time.process_time() - t0


def _peak(fn) -> float:
    """tracemalloc peak (bytes) during fn()."""
    tracemalloc.start()
    try:
        fn()
        return float(tracemalloc.get_traced_memory()[1])
    finally:
        tracemalloc.stop()


def _ours(y, names, taus, confidence=None):
    return stability(y, RATE, names, taus, "freq", confidence=confidence)


def _theirs(at, y, names, taus):
    return {k: getattr(at, k)(y, rate=RATE, data_type="freq", taus=taus) for k in names}


def _maxrel(res, theirs, names, ch: int = 0) -> dict[str, float]:
    out = {}
    for k in names:
        e = res.estimates[k]
        tt, dev = theirs[k][0], theirs[k][1]
        keep = np.isin(np.round(e.tau, 12), np.round(tt, 12)) & np.isfinite(e.dev[:, ch])
        ours = e.dev[keep, ch]
        ref = dev[np.isin(np.round(tt, 12), np.round(e.tau[keep], 12))]
        assert ours.size == ref.size and ours.size > 0, k
        out[k] = float(np.max(np.abs(ours / ref - 1.0)))
    return out


def _fmt_t(t: float) -> str:
    return f"{t:.3g}" if t < 100 else f"{t:.0f}"


def part_total_small(at, n: int, small_m: list[int], runs: int) -> str:
    y = _record(n, 1)
    taus = np.array(small_m, dtype=np.float64) / RATE
    rows = []
    for k in TOTAL:
        times, last = alternate(
            {
                "at": lambda k=k: _theirs(at, y, (k,), taus),
                "ours_ci": lambda k=k: _ours(y, (k,), taus, confidence=0.683),
                "ours": lambda k=k: _ours(y, (k,), taus),
            },
            runs,
        )
        rel = _maxrel(last["ours"], last["at"], (k,))[k]
        nt = int(np.isfinite(last["ours"].estimates[k].dev[:, 0]).sum())
        (full, t_full), = [_time(lambda k=k: _ours(y, (k,), "octave"))]
        nfull = int(np.isfinite(full.estimates[k].dev[:, 0]).sum())
        rows.append(
            f"| {k} | {nt} | {med_ms(times['at'])} | {med_ms(times['ours_ci'])} | {fmt_ratio(times, 'at', 'ours_ci')} "
            f"| {med_ms(times['ours'])} | {fmt_ratio(times, 'at', 'ours')} | {rel:.1e} | {nfull} τ in "
            f"{t_full * 1e3:.0f} ms |"
        )
    return (
        f"### Total family and Theo1 at N = {n:.0e} (same τ list, m = {', '.join(map(str, small_m))})\n\n"
        "| estimator | τ | allantools 2024.06 (values only; median) | tablebench **public call** (values + noise ID + "
        "EDF + χ² intervals; median) | speed-up, public call | tablebench values only (`confidence=None`; median) "
        "| speed-up, values only | max rel. diff | tablebench values only, full octave grid |\n"
        "|---|---|---|---|---|---|---|---|---|\n" + "\n".join(rows) + f"\n\n{runs} alternating repetitions "
        "(order swapped each repetition); speed-up = t_allantools / t_tablebench per repetition, median (range). Both "
        "libraries on the identical record and τ list, single-threaded (one BLAS thread; numpy's FFT and these loops "
        "are single-threaded anyway). The headline is the **public call** `stability(..., confidence=0.683)` — the "
        "figure a user gets; allantools computes values only, so the values-only column (`confidence=None`) is the "
        "like-for-like computation and is labelled so. allantools' per-τ loops make a full octave grid take minutes "
        "at this N, so only the listed m are compared; the last column is tablebench alone (one run).\n"
    )


def _three_channels(at, n: int, taus: np.ndarray, runs: int) -> tuple[list[float], dict[str, float]]:
    """Times of the public call on three channels at once, and the third channel's difference to allantools."""
    y3 = _record(n, 3, channels=3)
    times, last = alternate({"ours": lambda: _ours(y3, CLASSIC, taus, confidence=0.683)}, max(1, runs - 1))
    return times["ours"], _maxrel(
        last["ours"], _theirs(at, np.ascontiguousarray(y3[:, 2]), CLASSIC, taus), CLASSIC, 2
    )


def part_classic_big(at, n: int, runs: int) -> str:
    y = _record(n, 2)
    ms = m_grid(n + 1, "octave", RATE)
    taus = ms[ms <= n // 3] / RATE
    fns = {
        "at": lambda: _theirs(at, y, CLASSIC, taus),
        "ours_ci": lambda: _ours(y, CLASSIC, taus, confidence=0.683),
        "ours": lambda: _ours(y, CLASSIC, taus),
    }
    times, last = alternate(fns, runs)
    rel = _maxrel(last["ours"], last["at"], CLASSIC)
    t3, rel3 = _three_channels(at, n, taus, runs)
    peaks = {k: _peak(fn) for k, fn in fns.items()}
    rec = y.nbytes

    def row(label: str, k: str) -> str:
        r = "" if k == "at" else fmt_ratio(times, "at", k)
        return (
            f"| {label} | {np.median(times[k]):.2f} | {', '.join(f'{t:.2f}' for t in times[k])} | {r} | "
            f"{peaks[k] / 1e6:.0f} MB ({peaks[k] / rec:.1f}× record) |"
        )

    return (
        f"### ADEV, OADEV, MDEV, TOTDEV together at N = {n:.0e}, octave τ (m = 1 … {int(ms[ms <= n // 3].max())}, "
        f"{taus.size} τ, same list for both)\n\n"
        "| | median CPU time (s) | all repetitions (s) | speed-up vs allantools, median (range) | peak memory "
        "(tracemalloc) |\n|---|---|---|---|---|\n"
        + row("allantools 2024.06 (values, no intervals)", "at")
        + "\n"
        + row("tablebench `stability`, **public call** (values + noise ID + EDF + χ² intervals)", "ours_ci")
        + "\n"
        + row("tablebench `stability`, values only (`confidence=None`; like for like)", "ours")
        + "\n\n"
        f"{runs} alternating repetitions, order swapped each repetition. Three channels at once (public call, "
        f"3 × {n:.0e} samples, {len(t3)} runs, median): {np.median(t3):.2f} s = "
        f"{np.median(t3) / np.median(times['ours_ci']):.2f}× one channel (same run). Largest relative difference to "
        "allantools: "
        + ", ".join(f"{k} {v:.1e}" for k, v in rel.items())
        + " (one channel); "
        + ", ".join(f"{k} {v:.1e}" for k, v in rel3.items())
        + " (third of three channels).\n"
    )


def part_total_big(n: int) -> str:
    y = _record(n, 2)
    rows = []
    for k in TOTAL:
        tracemalloc.start()
        try:
            res, t = _time(lambda k=k: _ours(y, (k,), "octave"))
            peak = float(tracemalloc.get_traced_memory()[1])
        finally:
            tracemalloc.stop()
        e = res.estimates[k]
        del res
        rows.append(
            f"| {k} | {int(np.isfinite(e.dev[:, 0]).sum())} (m = {int(e.m.min())} … {int(e.m.max())}) | {t:.1f} | "
            f"{t / e.m.size:.2f} | {peak / 1e6:.0f} MB ({peak / y.nbytes:.1f}× record) |"
        )
    return (
        f"### Total family and Theo1 at N = {n:.0e}, full octave grid (allantools: not attempted)\n\n"
        "| estimator | τ | CPU time (s) | per τ (s) | peak memory (tracemalloc) |\n|---|---|---|---|---|\n"
        + "\n".join(rows)
        + "\n\nOne run each, under tracemalloc (time and memory of the same call; tracemalloc adds a little time). "
        "Peak memory: the phase, the "
        "autocorrelation's single in-place buffer (N + the grid's largest lag) and, at the largest τ (MTOT/HTOT/TTOT "
        "window 3m ≈ 0.6 N), at most two in-place FFT buffers of ≈ 6m points for the end-segment correlations (R "
        "released first); Theo1's long correlations and triangle sums are blocked (FFTs of ≤ N/8 points). "
        "Where the record-wide closed form’s rounding estimate exceeds 1e-10 (small m on "
        "this random-walk phase) it is evaluated block by block (O(N log B) per τ).\n"
    )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true", help="N = 2·10³ / 10⁶ instead of 10⁴ / 10⁷ (development)")
    ap.add_argument("--small-m", default="2,8,16", help="averaging factors of the N = 10⁴ comparison with allantools")
    ap.add_argument(
        "--runs", type=int, default=5, help="alternating repetitions per comparison (median and range reported)"
    )
    ap.add_argument("--no-write", action="store_true", help="print only, leave RESULTS.md alone")
    args = ap.parse_args()
    import allantools

    n_small, n_big = (2 * 10**3, 10**6) if args.quick else (10**4, 10**7)
    small_m = [int(v) for v in args.small_m.split(",")]
    load = os.getloadavg()
    parts = [
        part_total_small(allantools, n_small, small_m, args.runs),
        part_classic_big(allantools, n_big, args.runs),
        part_total_big(n_big),
    ]
    body = (
        "Record: white + random-walk rate noise with a ramp and an offset at 1 kHz (frequency data), one channel "
        f"unless stated. {load_note(load)} Conditions: {thread_note()}."
        f"{' **--quick run.**' if args.quick else ''}\n\n" + "\n".join(parts)
    )
    print(body)
    if not args.no_write:
        write_section("noise", "Noise analysis: stability family vs allantools (issue 16)", body)


if __name__ == "__main__":
    main()

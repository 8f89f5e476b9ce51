"""Benchmark: the stability family (analysis/noise/stability.py) against allantools, ratios measured in one run.

1. The total family and Theo1 (MTOTDEV, HTOTDEV, TTOTDEV, Theo1) at N = 10⁴ on the octave grid, against
   allantools on the same record and τ: time ratio and largest relative difference.
2. The same at N = 10⁷ (allantools cannot: minutes already at 10⁴): time and peak memory (tracemalloc)
   relative to the record, full octave grid.
3. ADEV, OADEV, MDEV, TOTDEV at N = 10⁷ against allantools: time ratio, difference, memory.

    python -m benchmarks.bench_noise            # as above
    python -m benchmarks.bench_noise --quick    # 10³ / 10⁶ instead of 10⁴ / 10⁷
"""

from __future__ import annotations

import argparse
import time
import tracemalloc

import numpy as np

from analysis.noise.stability import m_grid, stability
from benchmarks._results import write_section

TOTAL = ("mtotdev", "htotdev", "ttotdev", "theo1")
CLASSIC = ("adev", "oadev", "mdev", "totdev")


def _record(n: int, seed: int = 1) -> np.ndarray:
    rng = np.random.default_rng(seed)
    y = rng.normal(0.0, 1e-3, n)
    y += np.cumsum(rng.normal(0.0, 1e-7, n))
    y += 1e-9 * np.arange(n) + 0.2
    return y


def _measure(fn):
    tracemalloc.start()
    t0 = time.perf_counter()
    out = fn()
    dt = time.perf_counter() - t0
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    return out, dt, peak


def _ours(y, rate, names, taus):
    return stability(y, rate, names, taus, "freq", confidence=None)


def _theirs(at, y, rate, names, res):
    out = {}
    for k in names:
        e = res.estimates[k]
        keep = np.isfinite(e.dev[:, 0])
        out[k] = getattr(at, k)(y, rate=rate, data_type="freq", taus=e.tau[keep])
    return out


def _maxrel(res, theirs, names):
    rows, worst = [], 0.0
    for k in names:
        e = res.estimates[k]
        keep = np.isfinite(e.dev[:, 0])
        tt, dev = theirs[k][0], theirs[k][1]
        assert np.allclose(e.tau[keep], tt)
        rel = float(np.max(np.abs(e.dev[keep, 0] / dev - 1.0)))
        worst = max(worst, rel)
        rows.append((k, rel, int(keep.sum())))
    return rows, worst


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true", help="10³ / 10⁶ samples instead of 10⁴ / 10⁷")
    ap.add_argument(
        "--small-m",
        default="2,8,16",
        help="averaging factors of the N = 10⁴ comparison (allantools' total family runs Python loops of "
        "(N − 3m)·6m iterations per τ: the full octave grid takes hours on a shared machine)",
    )
    args = ap.parse_args()
    import allantools

    n_small, n_big = (10**3, 10**6) if args.quick else (10**4, 10**7)
    rate = 1000.0
    parts = []

    # 1. the total family at N = 10⁴ against allantools, each estimator timed alone
    y = _record(n_small)
    small_taus = np.array([int(v) for v in args.small_m.split(",")]) / rate
    rows = []
    for k in TOTAL:
        res, t_ours, _ = _measure(lambda k=k: _ours(y, rate, (k,), small_taus))
        theirs, t_ref, _ = _measure(lambda k=k, res=res: _theirs(allantools, y, rate, (k,), res))
        ((_, rel, nt),), _ = _maxrel(res, theirs, (k,))
        rows.append(f"| {k} | {nt} | {t_ref:.2f} | {t_ours:.4f} | **{t_ref / t_ours:.0f}×** | {rel:.1e} |")
    parts.append(
        f"### Total family and Theo1, N = {n_small:.0e}, m = {args.small_m}\n\n"
        "| estimator | τ points | allantools 2024.06 (s) | tablebench (s) | speed-up | max rel. diff |\n"
        "|---|---|---|---|---|---|\n" + "\n".join(rows) + "\n"
    )

    # 2. the same at N = 10⁷: time and memory
    yb = _record(n_big, 2)
    rows = []
    for k in ("mtotdev", "htotdev", "theo1"):
        res, t, peak = _measure(lambda k=k: _ours(yb, rate, (k,), "octave"))
        e = res.estimates[k]
        rows.append(
            f"| {k} | {int(np.isfinite(e.dev[:, 0]).sum())} (m ≤ {int(e.m.max())}) | {t:.1f} | "
            f"{peak / 1e6:.0f} MB ({peak / yb.nbytes:.1f}× record) |"
        )
    parts.append(
        f"### Total family and Theo1, N = {n_big:.0e}, octave τ (allantools: not attempted, O(N·m) Python loops; "
        "TTOTDEV is MTOTDEV·τ/√3, same cost)\n\n"
        "| estimator | τ points | time (s) | peak memory (tracemalloc) |\n|---|---|---|---|\n" + "\n".join(rows) + "\n"
    )

    # 3. the classic set at N = 10⁷ against allantools
    taus = m_grid(n_big + 1, "octave", rate)
    taus = taus[taus <= n_big // 3] / rate
    res, t_ours, peak_ours = _measure(lambda: _ours(yb, rate, CLASSIC, taus))
    theirs, t_ref, peak_ref = _measure(lambda: _theirs(allantools, yb, rate, CLASSIC, res))
    rows, worst = _maxrel(res, theirs, CLASSIC)
    parts.append(
        f"### ADEV, OADEV, MDEV, TOTDEV together, N = {n_big:.0e}, octave τ (m ≤ N/3)\n\n"
        "| | time (s) | peak memory (tracemalloc) |\n|---|---|---|\n"
        f"| allantools 2024.06 | {t_ref:.1f} | {peak_ref / 1e6:.0f} MB ({peak_ref / yb.nbytes:.1f}× record) |\n"
        f"| tablebench `stability` | {t_ours:.1f} | {peak_ours / 1e6:.0f} MB "
        f"({peak_ours / yb.nbytes:.1f}× record) |\n\n"
        f"**Speed-up {t_ref / t_ours:.1f}×**; largest relative difference "
        + ", ".join(f"{k} {r:.1e}" for k, r, _ in rows)
        + ".\n"
    )
    body = (
        "Record: white + random-walk + ramp rate noise at 1 kHz, one channel, no confidence intervals "
        "(noise identification and EDF add O(N) per τ). Both libraries run in this process, one after the other.\n\n"
        + "\n".join(parts)
    )
    print(body)
    write_section("noise", "Noise analysis: stability family vs allantools", body)


if __name__ == "__main__":
    main()

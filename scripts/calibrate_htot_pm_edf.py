"""Monte Carlo calibration of the HTOTVAR EDF for phase noise (white and flicker PM), which has no published fit.

Howe et al. (2000) give HTOTVAR EDF fits for FM noise only; for PM noise Stable32 falls back to the Hadamard EDF,
which is 1.5–2.9× too low (the total estimator's extended sub-segments add terms). This script measures the
EDF 2·E[σ̂²]²/Var[σ̂²] of HTOTVAR on Kasdin–Walter power-law phase noise and its ratio to the overlapping
Hadamard EDF of Greenhall's algorithm at the same N, m and α, and prints the geometric-mean ratio per α over
m = 2–3 and m ≥ 4. analysis/noise/confidence.py `_HTOT_PM_RATIO` holds the result of

    PYTHONPATH=. python scripts/calibrate_htot_pm_edf.py --n 256,4096,16384 --records 400

(N = 1024, the slow coverage test's record length, is deliberately left out of the calibration).
"""

from __future__ import annotations

import argparse

import numpy as np

from analysis.noise import confidence as ci
from analysis.noise.powerlaw import kasdin_phase
from analysis.noise.stability import stability


def ratios(n: int, alpha: int, records: int, seed: int) -> list[tuple[int, float, float]]:
    """(m, measured HTOTVAR EDF, its ratio to Greenhall's OHVAR EDF) over the octave grid (m ≥ 2, 3m < N)."""
    x = kasdin_phase(alpha, n, records, np.random.default_rng(seed))
    h = stability(x, 1.0, ("htotdev",), "octave", "phase", confidence=None).estimates["htotdev"]
    out = []
    for j, m in enumerate(h.m):
        v = h.dev[j] ** 2
        if m < 2 or 3 * m >= n or not np.isfinite(v).all():
            continue
        e = 2.0 * v.mean() ** 2 / v.var()
        out.append((int(m), float(e), float(e / ci.edf_greenhall(alpha, 3, int(m), n, True, False))))
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", default="256,4096,16384", help="record lengths, comma-separated")
    ap.add_argument("--records", type=int, default=400)
    ap.add_argument("--seed", type=int, default=900)
    a = ap.parse_args()
    for alpha in (2, 1):
        short, long_ = [], []
        for n in (int(v) for v in a.n.split(",")):
            for m, e, r in ratios(n, alpha, a.records, a.seed + alpha + n):
                print(f"α={alpha} N={n:6d} m={m:5d} EDF={e:9.1f} ratio to OHVAR's={r:5.2f}")
                (short if m < 4 else long_).append(r)
        g = lambda v: float(np.exp(np.mean(np.log(v))))  # noqa: E731
        print(f"α={alpha}: geometric-mean ratio m = 2–3: {g(short):.2f} ({len(short)} points); "
              f"m ≥ 4: {g(long_):.2f} ({len(long_)} points)")


if __name__ == "__main__":
    main()

"""Benchmark of the drift analysis (section "drift" of benchmarks/RESULTS.md).

Measured, each as a ratio against a reference in the same run:

- online RLS / extended LS (``analysis.drift.rls``) fed a static record sample by sample: samples/s, against
  real time (the record's sample rate) and against a straightforward per-sample numpy implementation;
- exact-ML and CSS ARMA(1,1) fits (``analysis.drift.arma.fit_arma``) against statsmodels' exact-ML ``ARIMA``
  fit, and the order search (``select_order``, ten models) on the same data;
- the sliding-window LM graph smoother against filterpy's Kalman filter + RTS smoother;
- the whole ``analyse_drift`` chain on a 30-minute record against the record's duration.

Run: ``python -m benchmarks.bench_drift`` (``--quick`` for smaller sizes).
"""

from __future__ import annotations

import argparse
import time
import warnings

import numpy as np

from analysis.drift.arma import fit_arma, select_order, simulate_arma
from analysis.drift.report import analyse_drift
from analysis.drift.rls import OnlineArma, batch_least_squares, lag_matrix
from analysis.drift.smoother import arma_state_space, sliding_window_smoother
from benchmarks._results import write_section


def _best(fn, repeat: int = 3) -> float:
    best = float("inf")
    for _ in range(repeat):
        t = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t)
    return best


def _numpy_rls(x: np.ndarray, p: int, n0: int) -> np.ndarray:
    """Reference: the textbook recursion with numpy arrays per sample (AR(p), λ = 1)."""
    theta, P = batch_least_squares(lag_matrix(x[:n0], p, p), x[p:n0])
    for t in range(n0, x.size):
        f = x[t - p : t][::-1]
        pf = P @ f
        k = pf / (1.0 + f @ pf)
        theta = theta + k * (x[t] - f @ theta)
        P = P - np.outer(k, pf)
    return theta


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true", help="smaller sizes (CI smoke run)")
    args = ap.parse_args()
    rate = 100.0
    minutes = 5 if args.quick else 30
    n = int(minutes * 60 * rate)
    rng = np.random.default_rng(1)
    rows = []
    n0 = 3000

    # 1. online estimator throughput
    lines = [
        "| model | samples | kernel samples/s | × real time (100 Hz) | × numpy per-sample |",
        "|---|---|---|---|---|",
    ]
    for p, q in ((1, 0), (1, 1), (2, 1), (3, 0), (3, 3)):
        x = simulate_arma([0.5, 0.1, 0.05][:p], [0.3, 0.1, 0.05][:q], 1.0, n, rng)

        def run(p: int = p, q: int = q, x: np.ndarray = x) -> None:
            OnlineArma(p, q).initialise(x[:n0]).feed(x[n0:])

        dt = _best(run)
        sps = (n - n0) / dt
        ref = ""
        if q == 0:
            m = min(n, 30000)
            dref = _best(lambda p=p, x=x, m=m: _numpy_rls(x[:m], p, n0), repeat=1)
            ref = f"{sps / ((m - n0) / dref):.0f}×"
        lines.append(f"| ARMA({p},{q}) | {n - n0} | {sps:.3g} | {sps / rate:.0f}× | {ref or '—'} |")
        rows.append(sps)
    online = "\n".join(lines)

    # 2. ML and CSS fits vs statsmodels exact ML
    from statsmodels.tsa.arima.model import ARIMA

    x = simulate_arma([0.9], [-0.4], 1.0, 5000, rng)
    t_ml = _best(lambda: fit_arma(x, 1, 1))
    t_css = _best(lambda: fit_arma(x, 1, 1, method="css"))
    t_sel = _best(lambda: select_order(x), repeat=1)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        t_sm = _best(lambda: ARIMA(x, order=(1, 0, 1), trend="n").fit(), repeat=1)
    fit_line = (
        f"ARMA(1,1) fit, n = 5000: exact ML {t_ml * 1e3:.1f} ms ({t_sm / t_ml:.0f}× faster), CSS {t_css * 1e3:.1f} ms "
        f"({t_sm / t_css:.0f}× faster), statsmodels ARIMA (exact ML) {t_sm * 1e3:.0f} ms; order search over the ten "
        f"ARMA(p ≤ 3, q ≤ 3, p ≥ q) by exact ML {t_sel:.2f} s"
    )

    # 3. LM smoother vs filterpy RTS
    from filterpy.kalman import KalmanFilter, rts_smoother

    ns = 2000 if args.quick else 5000
    ss = arma_state_space([0.9], [-0.4], 1.0, 1.0)
    z = simulate_arma([0.9], [-0.4], 1.0, ns, rng) + rng.standard_normal(ns)

    def rts() -> None:
        kf = KalmanFilter(dim_x=ss.m, dim_z=1)
        kf.F, kf.H, kf.Q, kf.R, kf.x, kf.P = ss.F, ss.H, ss.Q, np.array([[ss.R]]), ss.x0.copy(), ss.P0.copy()
        mu, cov, _, _ = kf.batch_filter(z)
        rts_smoother(mu, cov, [ss.F] * ns, [ss.Q] * ns)

    t_rts = _best(rts, repeat=1)
    t_lm = _best(lambda: sliding_window_smoother(ss, z, 400, 200), repeat=1)
    sm_line = (
        f"smoothing {ns} samples of ARMA(1,1) + noise: sliding-window LM (400/200) {t_lm:.2f} s, filterpy KF + RTS "
        f"{t_rts:.2f} s → ratio {t_lm / t_rts:.2f}"
    )

    # 4. whole chain
    x = simulate_arma([0.9], [0.4], (2 * 4.85e-6) ** 2, n, rng) + 2e-5
    t_all = _best(lambda: analyse_drift({"gyro_z": x}, rate), repeat=1)
    chain_line = (
        f"analyse_drift on a {minutes}-minute record at {rate:g} Hz ({n} samples, one channel): {t_all:.2f} s → "
        f"{n / rate / t_all:.0f}× faster than real time"
    )

    body = "\n".join(
        [
            "Online recursive (extended) least squares, fed sample by sample (generated plain-float kernel):",
            "",
            online,
            "",
            f"- minimum over ARMA(≤3,≤3): {min(rows):.3g} samples/s (target ≥ 1e5)",
            f"- {fit_line}",
            f"- {sm_line}",
            f"- {chain_line}",
        ]
    )
    print(body)
    write_section("drift", "Drift analysis (analysis/drift_*.py)", body)


if __name__ == "__main__":
    main()

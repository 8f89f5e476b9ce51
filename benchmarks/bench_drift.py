"""Benchmark of the drift analysis (section "drift" of benchmarks/RESULTS.md).

Measured, each as a ratio against a reference in the same run:

- online RLS / extended LS (``analysis.drift.rls``) fed a static record sample by sample: samples/s, against
  real time (the record's sample rate) and against a straightforward per-sample numpy implementation;
- exact-ML (mean estimated / fixed at zero) and CSS ARMA(1,1) fits (``analysis.drift.arma.fit_arma``) against
  statsmodels' exact-ML ``ARIMA`` on the same model, the order search (``select_order``, 16 models) against
  statsmodels fitting the same 16 models, and the published reference models of ``tests/data/drift``;
- the sliding-window LM graph smoother against filterpy's Kalman filter + RTS smoother;
- the whole ``analyse_drift`` chain on a 30-minute record against the record's duration.

Conditions (stated in the section): one BLAS/OpenMP thread for both sides (OPENBLAS_NUM_THREADS, OMP_NUM_THREADS,
MKL_NUM_THREADS = 1, set here before numpy loads, unless the caller set them); every comparison is of public calls
doing the same estimation (exact ML with the mean estimated ↔ statsmodels' trend "c"; fixed at zero ↔ "n";
statsmodels' own default optimiser and starting values); the single fits best of three runs on both sides after a
statsmodels warm-up call; the order search and the reference models one pass each on both sides.

Run: ``python -m benchmarks.bench_drift`` (``--quick`` for smaller sizes).
"""

from __future__ import annotations

import os

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")  # before numpy loads: the same thread setting for ours and the references

import argparse  # noqa: E402
import time  # noqa: E402
import warnings  # noqa: E402

import numpy as np  # noqa: E402

from analysis.drift.arma import fit_arma, select_order, simulate_arma  # noqa: E402
from analysis.drift.report import analyse_drift  # noqa: E402
from analysis.drift.rls import OnlineArma, batch_least_squares, lag_matrix  # noqa: E402
from analysis.drift.smoother import arma_state_space, sliding_window_smoother  # noqa: E402
from benchmarks._results import write_section  # noqa: E402


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


def _online_section(n: int, n0: int, rate: float, rng: np.random.Generator) -> tuple[str, list[float]]:
    """1. Online estimator throughput (samples/s), against a numpy per-sample recursion for pure AR."""
    rows = []
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
    return "\n".join(lines), rows


def _sm_fit(y: np.ndarray, p: int, q: int, trend: str) -> float:
    """statsmodels' exact ML fit (the reference), its log-likelihood."""
    from statsmodels.tsa.arima.model import ARIMA

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return float(ARIMA(y, order=(p, 0, q), trend=trend).fit().llf)


def _fit_section(rng: np.random.Generator) -> tuple[str, str]:
    """2. ML and CSS fits and the order search vs statsmodels exact ML (same model: mean estimated ↔ trend "c",
    fixed at 0 ↔ trend "n")."""
    x = simulate_arma([0.9], [-0.4], 1.0, 5000, rng) + 0.3
    t_ml = _best(lambda: fit_arma(x, 1, 1))
    t_ml0 = _best(lambda: fit_arma(x - x.mean(), 1, 1, include_mean=False))
    t_css = _best(lambda: fit_arma(x, 1, 1, method="css"))
    _sm_fit(x, 1, 1, "c")  # warm-up: statsmodels' first call pays its imports, not the fit
    t_sm = _best(lambda: _sm_fit(x, 1, 1, "c"))
    t_sm0 = _best(lambda: _sm_fit(x - x.mean(), 1, 1, "n"))
    t0 = time.perf_counter()
    sel = select_order(x)
    t_sel = time.perf_counter() - t0
    t0 = time.perf_counter()
    for p, q in sel.models:
        _sm_fit(x, p, q, "c")
    t_sel_sm = time.perf_counter() - t0
    fallbacks = sum("bfgs" in m.optimiser for m in sel.models.values())
    fit_line = (
        f"ARMA(1,1) fit, n = 5000, mean estimated: exact ML {t_ml * 1e3:.1f} ms vs statsmodels ARIMA (trend 'c') "
        f"{t_sm * 1e3:.0f} ms → {t_sm / t_ml:.0f}× faster; mean fixed at 0: {t_ml0 * 1e3:.1f} ms vs statsmodels "
        f"(trend 'n') {t_sm0 * 1e3:.0f} ms → {t_sm0 / t_ml0:.0f}×; CSS {t_css * 1e3:.1f} ms"
    )
    sel_line = (
        f"order search, all 16 ARMA(p ≤ 3, q ≤ 3) with mean, same record: {t_sel:.2f} s ({fallbacks} of 16 fits "
        f"needed the BFGS fallback) vs statsmodels fitting the same 16 models {t_sel_sm:.1f} s → "
        f"{t_sel_sm / t_sel:.1f}× faster"
    )
    return fit_line, sel_line


def _reference_section() -> str:
    """2b. The published reference models (tests/data/drift): all fits, ours vs statsmodels."""
    import json
    from pathlib import Path

    data = Path(__file__).resolve().parents[1] / "tests" / "data" / "drift"
    ys = np.genfromtxt(data / "gretl_arma_series.csv", delimiter=",", names=True)
    gretl = json.loads((data / "gretl_arma_estimates.json").read_text())["models"]
    cases = [(np.asarray(ys[m["series"]], float), m) for m in gretl.values()]
    dcpi = np.diff(np.loadtxt(data / "cpi.csv", skiprows=1))
    dwpi = np.diff(np.loadtxt(data / "wpi.csv", skiprows=1))
    cases += [(dcpi, m) for m in json.loads((data / "cpi_stata_estimates.json").read_text())["models"].values()]
    cases += [(dwpi, m) for m in json.loads((data / "wpi_stata_estimates.json").read_text())["models"].values()]
    t0 = time.perf_counter()
    for y, m in cases:
        fit_arma(y, m["p"], m["q"], include_mean=m["constant"])
    t_ref = time.perf_counter() - t0
    t0 = time.perf_counter()
    for y, m in cases:
        _sm_fit(y, m["p"], m["q"], "c" if m["constant"] else "n")
    t_ref_sm = time.perf_counter() - t0
    return (
        f"the {len(cases)} published reference models (gretl, Stata; 124–250 samples): {t_ref:.2f} s vs statsmodels "
        f"{t_ref_sm:.2f} s → {t_ref_sm / t_ref:.1f}× faster"
    )


def _smoother_section(quick: bool, rng: np.random.Generator) -> str:
    """3. The sliding-window LM smoother vs filterpy's Kalman filter + RTS smoother."""
    from filterpy.kalman import KalmanFilter, rts_smoother

    ns = 2000 if quick else 5000
    ss = arma_state_space([0.9], [-0.4], 1.0, 1.0)
    z = simulate_arma([0.9], [-0.4], 1.0, ns, rng) + rng.standard_normal(ns)

    def rts() -> None:
        kf = KalmanFilter(dim_x=ss.m, dim_z=1)
        kf.F, kf.H, kf.Q, kf.R, kf.x, kf.P = ss.F, ss.H, ss.Q, np.array([[ss.R]]), ss.x0.copy(), ss.P0.copy()
        mu, cov, _, _ = kf.batch_filter(z)
        rts_smoother(mu, cov, [ss.F] * ns, [ss.Q] * ns)

    t_rts = _best(rts, repeat=1)
    t_lm = _best(lambda: sliding_window_smoother(ss, z, 400, 200), repeat=1)
    return (
        f"smoothing {ns} samples of ARMA(1,1) + noise: sliding-window LM (400/200) {t_lm:.2f} s, filterpy KF + RTS "
        f"{t_rts:.2f} s → ratio {t_lm / t_rts:.2f}"
    )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true", help="smaller sizes (CI smoke run)")
    args = ap.parse_args()
    load_start = os.getloadavg()[0]
    rate = 100.0
    minutes = 5 if args.quick else 30
    n = int(minutes * 60 * rate)
    rng = np.random.default_rng(1)
    online, rows = _online_section(n, 3000, rate, rng)
    fit_line, sel_line = _fit_section(rng)
    ref_line = _reference_section()
    sm_line = _smoother_section(args.quick, rng)
    # 4. whole chain
    x = simulate_arma([0.9], [0.4], (2 * 4.85e-6) ** 2, n, rng) + 2e-5
    t_all = _best(lambda: analyse_drift({"gyro_z": x}, rate), repeat=1)
    chain_line = (
        f"analyse_drift on a {minutes}-minute record at {rate:g} Hz ({n} samples, one channel): {t_all:.2f} s → "
        f"{n / rate / t_all:.0f}× faster than real time"
    )
    threads = ", ".join(f"{v}={os.environ.get(v, 'unset')}" for v in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS"))
    load_line = (
        f"machine load (1-min load average, {os.cpu_count()} CPUs) {load_start:.1f} at start, {os.getloadavg()[0]:.1f} "
        "at end: absolute times scale with it; the ratios compare runs made minutes apart within it. Conditions: "
        f"{threads} for both sides; public calls on both sides (exact ML, same model); single fits best of 3 on "
        "both sides after a warm-up, the order search and reference models one pass each"
    )
    body = "\n".join(
        [
            load_line,
            "",
            "Online recursive (extended) least squares, fed sample by sample (generated plain-float kernel):",
            "",
            online,
            "",
            f"- minimum over ARMA(≤3,≤3): {min(rows):.3g} samples/s (target ≥ 1e5)",
            f"- {fit_line}",
            f"- {sel_line}",
            f"- {ref_line}",
            f"- {sm_line}",
            f"- {chain_line}",
        ]
    )
    print(body)
    write_section("drift", "Drift analysis (analysis/drift/)", body)

if __name__ == "__main__":
    main()

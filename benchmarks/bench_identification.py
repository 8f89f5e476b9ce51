"""Benchmark: streaming Kalman identification of the 18 accelerometer parameters over the ten-step sequence.

Feeds a synthetic ten-step run (holds + spins, noise 15 µg/√Hz) step by step into
:class:`analysis.identification.kalman.StreamingIdentifier` and reports, as ratios measured in the same run:

* identification speed relative to real time (data duration / identification wall time; only the
  identifier's ``update`` calls are timed, not the data generation);
* speed-up over textbook per-sample filterpy updates (timed on a subset, per sample);
* batch least squares (normal equations, and stacked QR) relative to the streaming filter on the same data,
  with the KF–batch agreement.

Full size: 1 kHz, holds of 400 s (≈ 10⁷ samples, 2.8 h). ``--quick``: 100 Hz, 60 s holds.
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from filterpy.kalman import KalmanFilter

from analysis.identification import batch as bi
from analysis.identification import model as am
from analysis.identification import plan as ip
from analysis.identification.kalman import StreamingIdentifier
from analysis.units import ARCSEC, DEG, MM, PPM, UG, UG_PER_G2
from benchmarks._results import write_section

G = 9.80
TRUTH = np.array(
    [100 * UG, -80 * UG, 120 * UG, 200 * PPM, -150 * PPM, 250 * PPM]
    + [a * ARCSEC for a in (30.0, -25.0, 20.0, 35.0, -30.0, 28.0)]
    + [20 * UG_PER_G2, -15 * UG_PER_G2, 25 * UG_PER_G2, -30 * MM, -30 * MM, -30 * MM]
)
SIGMA0 = am.sigma_from_display(
    {"bias": 1000.0, "scale": 1000.0, "misalignment": 100.0, "quadratic": 100.0, "size_effect": 30.0}
)


def main(argv: list[str] | None = None) -> None:
    """Run the benchmark and write its section of RESULTS.md."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="100 Hz and 60 s holds instead of 1 kHz and 400 s")
    args = ap.parse_args(argv)
    rate, hold = (100.0, 60.0) if args.quick else (1000.0, 400.0)
    spin = 30 * DEG
    rng = np.random.default_rng(1)
    sd = 15 * UG * np.sqrt(rate)
    r_var = np.full(3, sd**2)
    p0 = np.diag(SIGMA0**2)
    steps = ip.ten_step_sequence(G, rate, hold_s=hold, spin_rate=spin, revolutions=2, both_directions=True)
    kf = StreamingIdentifier(r_var, p0, sample_rate=rate)
    t_kf = 0.0
    n = 0
    keep = [] if args.quick else None
    for st in steps:
        fo = am.predict(TRUTH, st.f_ref, st.omega) + rng.normal(0.0, sd, st.f_ref.shape)
        t0 = time.perf_counter()
        kf.update(fo, st.f_ref, st.omega, st.label)
        t_kf += time.perf_counter() - t0
        n += fo.shape[0]
        if keep is not None:
            keep.append((fo, st.f_ref, st.omega))
    duration = n / rate
    x_rt = duration / t_kf
    nees = kf.nees(TRUTH)

    # Reference: per-sample filterpy updates (3-D measurement), timed on ≤ 3000 samples of the first spin.
    spin_step = next(s for s in steps if "spin" in s.label)
    m = min(3000, spin_step.f_ref.shape[0])
    h = am.design_matrix(spin_step.f_ref[:m], spin_step.omega[:m]) * SIGMA0
    z = am.predict(TRUTH, spin_step.f_ref[:m], spin_step.omega[:m]) - spin_step.f_ref[:m]
    ref = KalmanFilter(dim_x=18, dim_z=3)
    ref.P = np.eye(18)
    rr = np.diag(r_var)
    t0 = time.perf_counter()
    for k in range(m):
        ref.update(z[k].reshape(3, 1), R=rr, H=h[k])
    per_sample = (time.perf_counter() - t0) / m
    speedup = per_sample * n / t_kf

    rows = [
        "| quantity | value |",
        "|---|---|",
        f"| samples (rate, duration) | {n:.3g} ({rate:g} Hz, {duration / 3600:.2f} h) |",
        f"| streaming KF identification time | {t_kf:.2f} s |",
        f"| speed vs real time | **{x_rt:.0f}×** |",
        f"| speed-up vs per-sample filterpy updates | {speedup:.0f}× (per-sample {per_sample * 1e6:.0f} µs/sample) |",
        f"| NEES (χ²₁₈, mean 18) | {nees:.1f} |",
    ]
    if keep is not None:
        fo = np.concatenate([k[0] for k in keep])
        fr = np.concatenate([k[1] for k in keep])
        om = np.concatenate([k[2] for k in keep])
        del keep
        t0 = time.perf_counter()
        bn = bi.batch_identify(fo, fr, om, r_var, None, p0, method="normal")
        t_bn = time.perf_counter() - t0
        t0 = time.perf_counter()
        bq = bi.batch_identify(fo, fr, om, r_var, None, p0, method="qr")
        t_bq = time.perf_counter() - t0
        rel = np.max(np.abs(kf.estimate - bq.x) / (np.abs(bq.x) + bq.sigma))
        rel_nq = np.max(np.abs(bn.x - bq.x) / (np.abs(bq.x) + bq.sigma))
        rows += [
            f"| batch LS (normal equations) / streaming KF time | {t_bn / t_kf:.2f} |",
            f"| batch LS (stacked QR) / streaming KF time | {t_bq / t_kf:.1f} |",
            f"| max KF–batch(QR) difference, relative to abs(x)+σ | {rel:.1e} |",
            f"| max batch normal–QR difference, same scale | {rel_nq:.1e} |",
        ]
    body = (
        "Ten-step sequence (8 holds + spins at 30 °/s, 2 rev each direction, per base orientation), noise "
        "15 µg/√Hz, one filter update per step (exact information block).\n\n" + "\n".join(rows)
    )
    title = "Accelerometer identification (streaming KF)" + (" — quick" if args.quick else "")
    write_section("identification", title, body)
    print(body)


if __name__ == "__main__":
    main()

"""Benchmark: identification of the whole unit (accelerometer + gyro, 33 states) against the 18-state one.

Same synthetic ten-step-fast-spin data (holds + ±60 °/s spins, accelerometer 15 µg/√Hz, gyro 0.01 °/√h,
Earth rate at 48° latitude), identified (a) with the 18-state accelerometer model from the accelerometer
channels, (b) with the 33-state unit model (accelerometer + gyro) from all six channels. Reported as ratios
(b)/(a) of the wall time measured in the same run, interleaved, best of ``--repeat``: the streaming Kalman
filter (block updates) and the batch least squares (normal equations). Target (issue 25): ≤ 2×.

Full size: 1 kHz, 60 s holds, 10 revolutions per spin direction. ``--quick``: 100 Hz.
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np

from analysis import gimbal
from analysis.earth import earth_rate_enu
from analysis.identification import plan as ip
from analysis.identification.batch import batch_identify
from analysis.identification.kalman import StreamingIdentifier
from analysis.identification.specification import UnitModel, get_model
from analysis.units import ARCSEC, DEG, DEG_PER_HOUR, DEG_PER_SQRT_HOUR, G0, MM, PPM, UG, UG_PER_G2
from benchmarks._results import write_section

ACC = np.array(
    [100 * UG, -80 * UG, 120 * UG, 200 * PPM, -150 * PPM, 250 * PPM]
    + [a * ARCSEC for a in (30.0, -25.0, 20.0, 35.0, -30.0, 28.0)]
    + [20 * UG_PER_G2, -15 * UG_PER_G2, 25 * UG_PER_G2, -30 * MM, -30 * MM, -30 * MM]
)
GYR = np.array(
    [0.5 * DEG_PER_HOUR, -0.3 * DEG_PER_HOUR, 0.4 * DEG_PER_HOUR, 50 * PPM, -40 * PPM, 60 * PPM]
    + [a * ARCSEC for a in (10.0, -8.0, 6.0, 12.0, -9.0, 7.0)]
    + [0.02 * DEG_PER_HOUR / G0] * 3
)


def _data(rate: float, rng: np.random.Generator) -> tuple[list[tuple[str, np.ndarray, ...]], np.ndarray]:
    unit = UnitModel((get_model("accelerometer"), get_model("gyro")))
    steps = ip.ten_step_sequence(9.80, rate, hold_s=60.0, spin_rate=60 * DEG, revolutions=10, both_directions=True)
    r = np.array([(15 * UG) ** 2 * rate] * 3 + [(0.01 * DEG_PER_SQRT_HOUR) ** 2 * rate] * 3)
    x = np.concatenate([ACC, GYR])
    out = []
    for st in steps:
        earth = np.einsum("nji,j->ni", gimbal.body_to_nav(st.angles), earth_rate_enu(math.radians(48.15)))
        y = unit.predict(x, st.f_ref, st.omega, earth) + rng.normal(0.0, np.sqrt(r), (st.f_ref.shape[0], 6))
        out.append((st.label, y, st.f_ref, st.omega, earth))
    return out, r


def _kf(model, data, r, p0):  # noqa: ANN001, ANN202
    kf = StreamingIdentifier(r[: model.n_axes], p0, model=model)
    t0 = time.perf_counter()
    for label, y, f, om, ea in data:
        kf.update(y[:, : model.n_axes], f, om, label, earth=ea if model.n_axes == 6 else None)
    return time.perf_counter() - t0, kf.estimate


def _batch(model, data, r, p0):  # noqa: ANN001, ANN202
    y = np.concatenate([d[1][:, : model.n_axes] for d in data])
    f = np.concatenate([d[2] for d in data])
    om = np.concatenate([d[3] for d in data])
    ea = np.concatenate([d[4] for d in data]) if model.n_axes == 6 else None
    t0 = time.perf_counter()
    res = batch_identify(y, f, om, r[: model.n_axes], None, p0, model=model, earth=ea)
    return time.perf_counter() - t0, res.x


def main(argv: list[str] | None = None) -> None:
    """Run the benchmark and write its section of RESULTS.md."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="100 Hz instead of 1 kHz")
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args(argv)
    rate = 100.0 if args.quick else 1000.0
    data, r = _data(rate, np.random.default_rng(1))
    acc, unit = get_model("accelerometer"), UnitModel((get_model("accelerometer"), get_model("gyro")))
    p_acc = np.diag((10 * np.abs(ACC)) ** 2)
    p_unit = np.diag((10 * np.abs(np.concatenate([ACC, GYR]))) ** 2)
    best = {k: math.inf for k in ("kf18", "kf33", "b18", "b33")}
    for _ in range(args.repeat):
        best["kf18"] = min(best["kf18"], _kf(acc, data, r, p_acc)[0])
        best["kf33"] = min(best["kf33"], _kf(unit, data, r, p_unit)[0])
        best["b18"] = min(best["b18"], _batch(acc, data, r, p_acc)[0])
        best["b33"] = min(best["b33"], _batch(unit, data, r, p_unit)[0])
    _, x18 = _kf(acc, data, r, p_acc)
    _, x33 = _kf(unit, data, r, p_unit)
    n = sum(d[1].shape[0] for d in data)
    body = (
        f"Synthetic ten-step-fast-spin ({n} samples at {rate:g} Hz, ±60 °/s, 10 rev each way), best of "
        f"{args.repeat}, interleaved in one process.\n\n"
        "| identification | 18 states (accelerometer) | 33 states (accelerometer + gyro) | ratio |\n|---|---|---|---|\n"
        f"| streaming KF (block updates) | {best['kf18']:.3f} s | {best['kf33']:.3f} s | "
        f"**{best['kf33'] / best['kf18']:.2f}×** |\n"
        f"| batch least squares (normal equations) | {best['b18']:.3f} s | {best['b33']:.3f} s | "
        f"**{best['b33'] / best['b18']:.2f}×** |\n\n"
        f"Target ≤ 2×. The accelerometer block of the 33-state estimate equals the 18-state one to "
        f"{np.max(np.abs(x33[:18] - x18) / np.abs(x18)):.1e} relative.\n"
    )
    write_section("gyro_identification", "Whole-unit identification cost (issue 25)", body)
    print(body)


if __name__ == "__main__":
    main()

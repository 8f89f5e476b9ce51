"""Issue 25: the rate-transfer procedure on the simulated bench recovers the gyro's nonlinearity and asymmetry."""

from __future__ import annotations

from pathlib import Path

import pytest

from benches.rate_transfer import rate_transfer_run
from procedures.paths import resolve_procedure
from tests.simbench import bench_variant, run_procedure

G_SENS = "    g_sensitivity_dph_per_g: [[0.02, 0, 0], [0, 0.02, 0], [0, 0, 0.02]]"


@pytest.mark.slow
def test_rate_transfer_recovers_simulated_nonlinearity_and_asymmetry_within_u(tmp_path: Path) -> None:
    text = resolve_procedure("gyro-rate-transfer").read_text(encoding="utf-8")
    head, rest = text.split("  - group:\n", 1)
    z_group = "  - group:\n" + rest.split("  - group:\n")[2]  # the shipped procedure's z axis, as written
    proc = tmp_path / "rt-z.yaml"
    proc.write_text(head.replace("duration_s: 600", "duration_s: 60") + z_group, encoding="utf-8")
    bench = bench_variant(
        tmp_path, rate=100.0,
        gq=(G_SENS, G_SENS + "\n    quadratic_ppm_per_dps: [0.1, -0.15, 0.2]\n    asymmetry_ppm: [20.0, -30.0, 40.0]"),
    )  # fmt: skip
    run = run_procedure(tmp_path, bench, str(proc), seed=3)
    report = rate_transfer_run(run)
    (ax,) = report["axes"]
    assert ax["axis"] == "z"
    truth = ax["truth"]
    assert truth["nonlinearity_ppm"] > 50 and abs(truth["asymmetry_ppm"]) > 100  # a real effect to recover
    assert abs(ax["nonlinearity_ppm"] - truth["nonlinearity_ppm"]) < 2 * ax["u_nonlinearity_ppm"]
    assert abs(ax["asymmetry_ppm"] - truth["asymmetry_ppm"]) < 2 * ax["u_asymmetry_ppm"]
    assert abs(ax["scale_factor"] - truth["scale_factor"]) < 2 * ax["u_scale_factor"]

"""The gyro rate-transfer report of a recorded run (procedure ``gyro-rate-transfer``).

Per group (one body axis up on the outer gimbal), every hold and every constant-rate spin becomes one point:
the mean of the gyro output along the spun body axis against the mean reference rate along it — the table
rate from the encoder angles over time during a spin plus the Earth rate's component
(:func:`benches.identify.window_reference`, the identification's own reference). The maths is
:mod:`analysis.identification.rate_transfer` (IEEE Std 952/1431 definitions); the uncertainty of each
mean is the unit's angle random walk over the window plus its bias instability (independent per window).
When the recording carries the simulator's truth, the same figures computed from the true model at the
same points are reported beside the measured ones.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from analysis.identification.rate_transfer import rate_transfer_axis
from analysis.identification.specification import get_model
from analysis.units import PPM
from core.jsonio import write_json

from .identify import IdentificationError, configured_noise_variance, load_run, unit_model

AXES = "xyz"


def rate_transfer_run(run: str | Path) -> dict[str, Any]:
    """The rate-transfer report of a run: per axis the measured figures, with U = 2u, and the truth if known."""
    data = load_run(run, with_gyro=True)
    r_gyro = configured_noise_variance(data.config, unit_model(data.config))[3:]
    bi = np.asarray(data.config.unit.noise.gyro_bias_instability, dtype=float)
    groups: dict[str, list[Any]] = {}
    for w in data.windows:
        groups.setdefault(w.name.split("/")[0], []).append(w)
    truth = data.truth or {}
    full = get_model("gyro", full_g=True, quadratic=True, asymmetry=True)
    x_true = np.array([truth.get(n, 0.0) for n in full.names]) if "gyro_S_x" in truth else None
    axes: list[dict[str, Any]] = []
    lines = [f"{'axis':4s} {'K − 1 (ppm)':>14s} {'nonlinearity (ppm FS)':>26s} {'asymmetry (ppm)':>22s}  truth NL/A"]
    for name, ws in groups.items():
        spins = [w for w in ws if w.kind == "spin"]
        if len(spins) < 4:
            continue
        axis = int(np.argmax(np.mean([np.abs(w.omega).mean(0) for w in spins], axis=0)))
        assert all(w.gyro is not None and w.earth is not None for w in ws)
        rin = np.array([float(np.mean(w.omega[:, axis] + w.earth[:, axis])) for w in ws])  # type: ignore[index]
        rout = np.array([float(np.mean(w.gyro[:, axis])) for w in ws])  # type: ignore[index]
        n = np.array([w.t.size for w in ws], dtype=float)
        u = np.sqrt(r_gyro[axis] / n + bi[axis] ** 2)
        res = rate_transfer_axis(AXES[axis], rin, rout, u)
        item: dict[str, Any] = {"group": name, **res.as_dict()}
        t_txt = ""
        if x_true is not None:
            y_true = [full.predict(x_true, w.f_ref, w.omega, w.earth)[:, axis].mean() for w in ws]
            tr = rate_transfer_axis(AXES[axis], rin, np.array(y_true), u)
            item["truth"] = {"nonlinearity_ppm": tr.nonlinearity_ppm, "asymmetry_ppm": tr.asymmetry_ppm,
                             "scale_factor": tr.scale_factor}  # fmt: skip
            t_txt = f"  {tr.nonlinearity_ppm:.2f} / {tr.asymmetry_ppm:.2f}"
        axes.append(item)
        lines.append(
            f"{AXES[axis]:4s} {(res.scale_factor - 1) / PPM:8.2f} ± {2 * res.u_scale_factor / PPM:4.2f} "
            f"{res.nonlinearity_ppm:17.2f} ± {2 * res.u_nonlinearity_ppm:5.2f} "
            f"{res.asymmetry_ppm:14.2f} ± {2 * res.u_asymmetry_ppm:5.2f}{t_txt}"
        )
    if not axes:
        raise IdentificationError(
            f"{data.path}: no group with spins in both directions at several rates; run gyro-rate-transfer"
        )
    lines.append("± = U (k = 2); K − 1: scale-factor error; FS: full-scale output |K| × max |rate|")
    return {"format": "tablebench-rate-transfer", "format_version": 1, "recording": data.path.name, "axes": axes,
            "summary": "\n".join(lines)}  # fmt: skip


def write_rate_transfer(report: dict[str, Any], path: str | Path) -> Path:
    """Write the report (strict JSON: a non-finite number raises)."""
    return write_json(path, {k: v for k, v in report.items() if k != "summary"}, nonfinite="error")


__all__ = ["rate_transfer_run", "write_rate_transfer"]

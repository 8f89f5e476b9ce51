"""A synthetic run folder for the certificate tests: a fake-bench recording plus a calibration.json fixture.

The recording comes from the orchestrator itself (``tests.fakes`` devices + ``Runner`` + ``Hdf5Recorder``) on a
ten-step-like procedure (three base orientations, seven 45° steps each, one constant-rate spin each). The
``calibration.json`` follows ``benches/CALIBRATION_FORMAT.md`` with realistic values: its covariance is the
honest posterior (P0⁻¹ + Σ HᵀR⁻¹H)⁻¹ of the recorded geometry, the estimate a seeded draw around a typical truth
(b 100 µg, S 200 ppm, τ 30″, d 20 µg/g², r 30 mm), residual statistics drawn from the noise model. When the real
simulated bench and identification exist, swap :func:`make_run_folder` for a real ``tablebench run``.
"""

from __future__ import annotations

import hashlib
import json
import math
from pathlib import Path

import numpy as np

from analysis.identification.budget import data_information
from analysis.identification.model import PARAM_KINDS, PARAM_NAMES
from analysis.units import ARCSEC, MM, PPM, UG, UG_PER_G2, display_unit, to_display
from benches.bench_config import load_bench
from benches.calibration_integrity import with_integrity
from benches.certificate.budget import step_geometry
from benches.recording import Hdf5Recorder, open_recording
from benches.runner import Runner
from tests import REPO_ROOT
from tests.fakes import FakeClock, FakeStep, FakeTable, FakeUnit

RATE = 100.0
SIM_BENCH = REPO_ROOT / "benches" / "sim.yaml"
BENCH = load_bench(SIM_BENCH)
G = BENCH.site.g
TRUTH = np.array(
    [100 * UG, -80 * UG, 120 * UG, 200 * PPM, -150 * PPM, 250 * PPM]
    + [30 * ARCSEC, -25 * ARCSEC, 20 * ARCSEC, 35 * ARCSEC, -30 * ARCSEC, 15 * ARCSEC]
    + [20 * UG_PER_G2, -15 * UG_PER_G2, 10 * UG_PER_G2, -30 * MM, -28 * MM, -32 * MM]
)
PRIOR = np.array(
    [1000 * UG] * 3 + [1000 * PPM] * 3 + [200 * ARCSEC] * 6 + [100 * UG_PER_G2] * 3 + [100 * MM] * 3, dtype=float
)
NOISE_DENSITY = 15 * UG  # m/s²/√Hz

BENCH_TEXT = BENCH.text  # the shipped simulated bench: site, table accuracy, limits, identities


def ten_step_like(hold_s: float = 2.0, spin_rate_dps: float = 30.0) -> list[FakeStep]:
    """Three base orientations × (eight holds 45° apart + one revolution at ``spin_rate_dps``)."""
    r = math.radians
    steps: list[FakeStep] = [FakeStep(0, "warm-up", "warmup", "A", (0.0, 0.0, 0.0), duration=2.0)]
    bases = {"A": ((0.0, 0.0, 0.0), 2), "B": ((r(-90), r(-90), 0.0), 1), "C": ((r(90), 0.0, r(90)), 1)}
    for grp, (base, axis) in bases.items():
        for k in range(8):
            ang = list(base)
            ang[axis] += r(45 * k)
            steps.append(FakeStep(len(steps), f"{grp}/hold-{k}", "hold", grp, tuple(ang), duration=hold_s, settle=0.3))
        steps.append(
            FakeStep(
                len(steps),
                f"{grp}/spin",
                "spin",
                grp,
                None,
                axis=axis,
                rate=r(spin_rate_dps),
                duration=360.0 / spin_rate_dps,
                settle=0.5,
            )
        )
        steps.append(FakeStep(len(steps), f"{grp}/back", "move", grp, base))
    return steps


def record(path: Path, *, fail_after: float | None = None, bench_text: str = BENCH_TEXT) -> str:
    """Record the fake procedure to ``path``; returns the run status."""
    clock = FakeClock(RATE)
    steps = ten_step_like()
    proc_text = "\n".join(f"{s.index}: {s.name} {s.kind} {s.angles} {s.axis} {s.rate}" for s in steps)
    rec = Hdf5Recorder(
        path,
        attrs={
            "software_version": "0.1.0",
            "seed": 7,
            "bench_name": BENCH.name,
            "procedure_name": "ten-step-like",
            "procedure_sha256": hashlib.sha256(proc_text.encode()).hexdigest(),
            "sample_rate_hz": RATE,
            "simulated": True,
            "transport": "in-process",
            "site_g": G,
            "site_g_source": BENCH.site.g_source,
        },
        bench_text=bench_text,
        procedure_text=proc_text,
        truth={n: float(v) for n, v in zip(PARAM_NAMES, TRUTH, strict=True)},
        checkpoint_samples=5000,
    )
    try:
        result = Runner(
            FakeTable(clock, speed=math.radians(60.0), fail_after=fail_after),
            FakeUnit(clock),
            steps,
            rec,
            position_tolerance=1e-6,
            block_seconds=0.5,
        ).run()
    finally:
        rec.close()
    return result.status


def _sha256(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for chunk in iter(lambda: fh.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


def _condition(info: np.ndarray) -> float | str:
    """The information matrix's condition number as calibration.json states it (the writer's text when ∞)."""
    c = float(np.linalg.cond(info))
    return c if math.isfinite(c) else "infinite (rank-deficient)"


def calibration_fixture(run: Path, *, seed: int = 3, shift: dict[str, float] | None = None) -> dict:
    """A ``calibration.json`` dict for the recording in ``run`` (see the module docstring)."""
    rng = np.random.default_rng(seed)
    noise_var = np.full(3, NOISE_DENSITY**2 * RATE)
    with open_recording(run / "recording.h5") as f:
        geo = step_geometry(f, G, None)
    info = data_information(geo, noise_var)
    p0_inv = np.diag(1.0 / PRIOR**2)
    cov = np.linalg.inv(p0_inv + info)
    cov = 0.5 * (cov + cov.T)
    x = TRUTH + np.linalg.cholesky(cov) @ rng.standard_normal(18)
    for name, dv in (shift or {}).items():
        x[PARAM_NAMES.index(name)] += dv
    sigma = np.sqrt(np.diag(cov))
    # identifiable: the data (not the prior) determine the parameter
    identifiable = sigma < 0.3 * PRIOR
    per_step = []
    for g in geo:
        n = g.samples
        mean = rng.standard_normal(3) * np.sqrt(noise_var / n) + rng.standard_normal(3) * 0.5 * UG
        rms = np.sqrt(noise_var * (1 + rng.standard_normal(3) * math.sqrt(2 / n)) + mean**2)
        per_step.append({"name": g.name, "kind": g.kind, "samples": n, "mean": mean.tolist(), "rms": rms.tolist()})
    # convergence history: posterior after each step
    hist_est, hist_sig, hist_t, hist_step = [], [], [], []
    acc = p0_inv.copy()
    for k, g in enumerate(geo):
        acc = acc + data_information([g], noise_var)
        pk = np.linalg.inv(acc)
        sk = np.sqrt(np.clip(np.diag(pk), 0, None))
        extra = np.sqrt(np.clip(sk**2 - sigma**2, 0, None))
        hist_est.append((x + extra * rng.standard_normal(18)).tolist())
        hist_sig.append(sk.tolist())
        hist_t.append(float(sum(h.samples for h in geo[: k + 1]) / RATE))
        hist_step.append(g.name)
    params = {}
    for i, (name, kind) in enumerate(zip(PARAM_NAMES, PARAM_KINDS, strict=True)):
        params[name] = {
            "value": float(x[i]),
            "sigma": float(sigma[i]),
            "unit": {"bias": "m/s^2", "scale": "1", "misalignment": "rad", "quadratic": "s^2/m"}.get(kind, "m"),
            "kind": kind,
            "display_unit": display_unit(kind),
            "display_value": float(to_display(kind, x[i])),
            "display_sigma": float(to_display(kind, sigma[i])),
            "identifiable": bool(identifiable[i]),
            "prior_sigma": float(PRIOR[i]),
        }
    unident = [n for n, ok in zip(PARAM_NAMES, identifiable, strict=True) if not ok]
    with open_recording(run / "recording.h5") as f:
        status = f.header.status
    return {
        "format": "tablebench-calibration",
        "format_version": 1,
        "recording": "recording.h5",
        "recording_sha256": _sha256(run / "recording.h5"),
        "software_version": "0.1.0",
        "method": "kalman",
        "model": "f_out = f + (S + T) f + b + D (f∘f) + diag(r) c(ω)",
        "parameter_names": list(PARAM_NAMES),
        "parameters": params,
        "covariance": cov.tolist(),
        "information": {"rank": 18, "condition": _condition(info), "unidentifiable": unident},
        "measurement_noise": {"variance": noise_var.tolist(), "source": "configured"},
        "residuals": {"rms": np.sqrt(noise_var).tolist(), "per_step": per_step},
        "plan": {
            "predicted_sigma": dict(zip(PARAM_NAMES, sigma.tolist(), strict=True)),
            "rank": 18,
            "warnings": [f"{n} not identified: predicted 1σ exceeds 30 % of the prior" for n in unident],
        },
        "truth": None,
        "history": {"time": hist_t, "step": hist_step, "estimate": hist_est, "sigma": hist_sig},
        "run": {
            "status": status,
            "bench_name": BENCH.name,
            "procedure_name": "ten-step-like",
            "procedure_sha256": "",
            "seed": 7,
            "created_utc": "",
            "transport": "in-process",
            "site": {
                "latitude_deg": math.degrees(BENCH.site.latitude),
                "height_m": BENCH.site.height,
                "g": G,
                "g_source": BENCH.site.g_source,
            },
            "unit": {"model": BENCH.unit.model, "serial_number": BENCH.unit.serial_number},
            "table": {
                "model": BENCH.turntable.model,
                "serial_number": BENCH.turntable.serial_number,
                "attitude_accuracy": BENCH.turntable.attitude_accuracy,
            },
            "temperature_k": {"mean": 298.15, "min": 298.15, "max": 298.15},
        },
        "warnings": ["size effect r identified only from 30 °/s spins in one direction"],
    }


def make_run_folder(
    run: Path, *, fail_after: float | None = None, shift: dict[str, float] | None = None, seed: int = 3
) -> Path:
    """Record the fake run into ``run`` and write its ``calibration.json``; returns ``run``."""
    run.mkdir(parents=True, exist_ok=True)
    record(run / "recording.h5", fail_after=fail_after)
    cal = with_integrity(calibration_fixture(run, seed=seed, shift=shift))  # as identify writes it (tamper evidence)
    (run / "calibration.json").write_text(json.dumps(cal, indent=1), encoding="utf-8")
    return run


def add_analyses(run: Path) -> None:
    """Small noise / periodic / drift outputs in the formats of the analysis commands, with one PNG."""
    import io

    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    noise = {
        "channels": {
            "accel_x": {
                "terms": {"N": {"value": 1.47e-4, "sigma": 1.5e-7, "unit": "m/s^1.5"}},
                "terms_display": {
                    "N": {"value": 14.99, "sigma": 0.015, "unit": "µg/√Hz"},
                    "B": {"value": 2.66, "sigma": 0.81, "unit": "µg"},
                },
            }
        }
    }
    periodic = {
        "channels": {
            "gyro_z": {
                "unit": "rad/s",
                "terms": [
                    {
                        "frequency_hz": 12.5,
                        "frequency_sigma_hz": 1e-4,
                        "amplitude": 2e-5,
                        "amplitude_unit": "rad/s",
                        "phase_rad": 0.3,
                    }
                ],
                "offset": 0.0,
                "residual_rms_before": 3e-5,
                "residual_rms_after": 1e-5,
            }
        }
    }
    drift = {
        "channels": {
            "gyro_x": {
                "model": {"p": 1, "q": 1, "phi": [0.95], "theta": [-0.4], "sigma2": 1e-12, "criterion": "bic"},
                "tests": {"ljung_box": {"statistic": 12.1, "threshold": 31.4, "verdict": "pass"}},
            }
        }
    }
    for kind, data in (("noise", noise), ("periodic", periodic), ("drift", drift)):
        (run / kind).mkdir(exist_ok=True)
        (run / kind / f"{kind}.json").write_text(json.dumps(data), encoding="utf-8")
    fig = Figure(figsize=(4, 2.5))
    FigureCanvasAgg(fig)
    ax = fig.subplots()
    tau = np.logspace(-3, 2, 30)
    ax.loglog(tau, 15 * UG / np.sqrt(tau))
    ax.set_title("Allan deviation (fixture)")
    buf = io.BytesIO()
    fig.savefig(buf, format="png", metadata={"Software": None})
    (run / "noise" / "noise.png").write_bytes(buf.getvalue())

"""Nominal trajectory for the planner, and the ``tablebench check`` command (exit codes 0 / 2)."""

from __future__ import annotations

import math
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from analysis.gimbal import body_to_nav
from benches.cli import main
from drivers.protocols import AxisLimits
from procedures.compiler import compile_procedure
from procedures.loader import load_procedure
from procedures.paths import PACKAGE_BENCHES, default_bench_path, resolve_procedure
from procedures.trajectory import nominal_samples
from tests.procedures.tables import SIM_LIMITS, D


def test_nominal_samples_weights_and_spin_geometry() -> None:
    comp = compile_procedure(load_procedure(resolve_procedure("ten-step-fast-spin")), limits=SIM_LIMITS)
    rate = 200.0
    pts = nominal_samples(comp, rate, points_per_revolution=360, limits=SIM_LIMITS)
    acq = [s for s in comp.steps if s.kind in ("warmup", "hold", "spin")]
    assert [p.step for p in pts] == acq
    for p in pts:
        assert p.weights.sum() == pytest.approx(p.step.duration * rate, rel=1e-12)
        assert p.angles.shape == p.rates.shape == (len(p.weights), 3)
        if p.step.kind == "hold":
            assert len(p.weights) == 1 and np.all(p.rates == 0)
            assert np.allclose(p.angles[0], p.step.angles)
        if p.step.kind == "spin":
            revs = abs(p.step.rate) * p.step.duration / (2 * math.pi)
            assert len(p.weights) == round(revs * 360)
            assert np.allclose(p.rates[:, p.step.axis], p.step.rate)
            span = p.angles[-1, p.step.axis] - p.angles[0, p.step.axis]
            assert span == pytest.approx(p.step.rate * p.step.duration * (1 - 1 / len(p.weights)))
            # a whole number of turns: gravity in the body frame averages to zero about the spin axis
            g_body = body_to_nav(p.angles)[:, 2, :]  # rows: Up in body coordinates
            axis = int(p.step.body_axis[-1] == "y") + 2 * int(p.step.body_axis[-1] == "z")
            mean = np.average(g_body, axis=0, weights=p.weights)
            assert np.delete(np.abs(mean), axis).max() < 1e-9


def test_nominal_samples_caps_points() -> None:
    comp = compile_procedure(load_procedure(resolve_procedure("ten-step")), limits=SIM_LIMITS)
    pts = nominal_samples(comp, 100.0, max_points_per_step=50)
    assert max(len(p.weights) for p in pts) == 50
    with pytest.raises(ValueError):
        nominal_samples(comp, 0.0)


@pytest.fixture
def fake_bench(monkeypatch: pytest.MonkeyPatch) -> dict:
    """Replace the bench loader by a sim-like bench (keeps these tests independent of the bench files)."""
    import benches.session as session

    state = {"limits": SIM_LIMITS, "rate": 200.0, "paths": []}

    def load_bench(path):
        state["paths"].append(Path(path))
        return SimpleNamespace(
            name="fake-sim",
            path=Path(path),
            turntable=SimpleNamespace(limits=state["limits"]),
            unit=SimpleNamespace(mounting=np.eye(3), sample_rate=state["rate"],
                                 noise=SimpleNamespace(arw=np.full(3, 3e-6))),  # a usable gyro noise  # fmt: skip
        )

    monkeypatch.setattr(session, "load_bench", load_bench)
    return state


def test_check_ok(fake_bench: dict, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["check", "ten-step"]) == 0
    out = capsys.readouterr().out
    assert "x South, y Down, z East" in out and "OK:" in out and "estimated duration" in out
    assert fake_bench["paths"][-1] == default_bench_path()
    assert main(["check", "static-noise.yaml", "--set", "duration_s=60", "--quiet"]) == 0
    out = capsys.readouterr().out
    assert out.count("\n") == 1 and "0:11:10" in out  # 600 s warm-up + 60 s record + 2 × 5 s settle


def test_check_errors_exit_2_with_one_line(
    fake_bench: dict, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    fake_bench["limits"] = (SIM_LIMITS[0], SIM_LIMITS[1], AxisLimits(rate_max=20 * D, accel_max=200 * D))
    assert main(["check", "ten-step-fast-spin"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1
    assert "ten-step-fast-spin.yaml:" in err and "step 'A/spin+'" in err and "allowed" in err
    bad = tmp_path / "bad.yaml"
    bad.write_text("name: bad\nsteps:\n  - orient: {x: East, y: North}\n  - hold: {duration_s: 0.001}\n")
    assert main(["check", str(bad)]) == 2
    err = capsys.readouterr().err
    assert f"{bad}:4: step 'hold'" in err and "shorter than one sample" in err
    bad.write_text("name: bad\nsteps:\n  - twirl: {}\n")
    assert main(["check", str(bad)]) == 2
    assert f"{bad}:3:" in capsys.readouterr().err
    assert main(["check", "no-such-procedure"]) == 2
    assert main(["check", "static-noise", "--set", "duration_s"]) == 2
    assert "expected NAME=NUMBER" in capsys.readouterr().err


def test_check_help_has_examples(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as info:
        main(["check", "--help"])
    assert info.value.code == 0
    assert "examples:" in capsys.readouterr().out


@pytest.mark.parametrize("name", ["ten-step", "ten-step-fast-spin", "twenty-four-position", "static-noise"])
def test_check_shipped_on_the_sim_bench(name: str, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["check", name, "--bench", str(PACKAGE_BENCHES / "sim.yaml"), "--quiet"]) == 0
    assert "OK:" in capsys.readouterr().out


def test_warmup_at_unknown_attitude_has_nan_angles() -> None:
    from procedures.loader import load_procedure_text

    proc = load_procedure_text("name: t\nsteps:\n  - warmup: {duration_s: 3}\n  - orient: {x: East, y: North}\n")
    (p,) = nominal_samples(compile_procedure(proc, limits=SIM_LIMITS), 10.0)
    assert np.isnan(p.angles).all() and p.weights.sum() == 30.0


SMOKE = """\
name: smoke
description: compiled attitudes and spins on the simulated bench
defaults: {settle_s: 1, hold_s: 2}
steps:
  - warmup: {duration_s: 1, at: {x: East, y: North, z: Up}}
  - group:
      name: B
      steps:
        - orient: {x: South, y: Down, z: East}
        - hold: {}
        - step_rotate: {axis: x, angle_deg: 90, count: 2}
        - spin: {axis: x, rate_dps: 90, direction: both, revolutions: 1}
  - group:
      name: C
      steps:
        - orient: {x: Down, y: West, z: North}
        - hold: {}
        - step_rotate: {axis: -z, angle_deg: 90, count: 1}
"""


def test_compiled_attitudes_on_the_simulated_bench(tmp_path: Path) -> None:
    """End to end through ``tablebench run``: the simulator's accelerometers see gravity where the compiler says."""
    from benches.recording import open_recording

    proc = tmp_path / "smoke.yaml"
    proc.write_text(SMOKE)
    out = tmp_path / "run"
    assert main(["run", "--procedure", str(proc), "--out", str(out), "--plain", "--seed", "3"]) == 0
    with open_recording(out) as rec:
        smp, steps = rec.samples(), rec.steps
        accel, gyro = smp.accel, smp.gyro
    up_in_body = {  # expected direction of the specific force (Up) in body axes, worked out by hand from the words
        "B/hold": (0, -1, 0),  # B: x South, y Down, z East
        "B/hold-1": (0, 0, 1),  # B turned +90° about body x: z Up
        "B/hold-2": (0, 1, 0),  # +180°: y Up
        "C/hold": (-1, 0, 0),  # C: x Down, y West, z North
        "C/hold-1": (0, -1, 0),  # C turned -90° about body z: x East, y Down
    }
    seen = set()
    for s in steps:
        name = s.name
        a0, a1 = s.acq_start, s.acq_end
        if name in up_in_body:
            f_mean = accel[a0:a1].mean(axis=0)
            assert np.allclose(f_mean / np.linalg.norm(f_mean), up_in_body[name], atol=2e-3), name
            seen.add(name)
        if name in ("B/spin+", "B/spin-"):
            w = gyro[a0:a1].mean(axis=0)
            assert np.allclose(w, (math.copysign(90 * D, 1 if name.endswith("+") else -1), 0, 0), atol=1e-3)
            seen.add(name)
    assert len(seen) == 7

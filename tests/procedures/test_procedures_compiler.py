"""Compiler: attitudes, gimbal selection, limits, names, durations; checked against independent geometry."""

from __future__ import annotations

import math
import textwrap
from dataclasses import replace

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from analysis.gimbal import body_rate, body_to_nav
from core.yaml_source import ConfigError
from procedures.compiler import compile_procedure
from procedures.loader import load_procedure, load_procedure_text
from procedures.paths import resolve_procedure
from procedures.steps import CompiledProcedure, move_time
from tests.procedures.tables import SIM_LIMITS, D

# the spec's direction words, restated here rather than imported (analysis.gimbal.ENU_DIRECTIONS): an independent table
ENU = {
    "East": (1, 0, 0),
    "West": (-1, 0, 0),
    "North": (0, 1, 0),
    "South": (0, -1, 0),
    "Up": (0, 0, 1),
    "Down": (0, 0, -1),
}
BODY = {"x": np.array([1.0, 0, 0]), "y": np.array([0, 1.0, 0]), "z": np.array([0, 0, 1.0])}
# docs/methods/accelerometer-calibration.md: base orientation → (body x, y, z) in ENU, reference body axis
SPEC_BASES = {
    "A": (("East", "North", "Up"), "y"),
    "B": (("South", "Down", "East"), "x"),
    "C": (("Down", "West", "North"), "z"),
}
# Cube-group mountings C_b^t to exercise the gimbal choice with non-identity mounting.
MOUNTINGS = [
    None,
    Rotation.from_euler("z", 90, degrees=True).as_matrix(),
    Rotation.from_euler("xz", [90, 180], degrees=True).as_matrix(),
]


def _compile(name: str, limits=SIM_LIMITS, mounting=None) -> CompiledProcedure:
    return compile_procedure(load_procedure(resolve_procedure(name)), limits=limits, mounting=mounting)


def _text(text: str, limits=SIM_LIMITS, mounting=None) -> CompiledProcedure:
    proc = load_procedure_text(textwrap.dedent(text).lstrip("\n"), "p.yaml")
    return compile_procedure(proc, limits=limits, mounting=mounting)


def _c(words) -> np.ndarray:
    return np.array([ENU[w] for w in words], dtype=float).T


def _signed(axis: str) -> np.ndarray:
    return BODY[axis[-1]] * (-1.0 if axis[0] == "-" else 1.0)


def _check_rotations(comp: CompiledProcedure, mounting=None) -> int:
    """Every body-axis move and spin realises the requested body rotation (independent of the compiler's choice)."""
    checked = 0
    prev = None
    for step, start in zip(comp.steps, comp.start_angles, strict=True):
        if step.kind == "move" and step.body_axis is not None:
            assert prev is not None
            c0 = body_to_nav(np.asarray(start), mounting)
            c1 = body_to_nav(np.asarray(step.angles), mounting)
            rel = Rotation.from_matrix(c0.T @ c1).as_rotvec()  # body-frame rotation from start to target
            angle = np.linalg.norm(rel)
            assert np.allclose(rel / angle, _signed(step.body_axis), atol=1e-9), step.name
            checked += 1
        if step.kind == "spin":
            rates = np.zeros(3)
            rates[step.axis] = step.rate
            for phase in (0.0, 1.0, 2.5):  # the body rate is along the body axis at any angle of that gimbal
                ang = np.asarray(start, dtype=float).copy()
                ang[step.axis] += phase
                w = body_rate(ang, rates, mounting)
                assert np.allclose(w, abs(step.rate) * _signed(step.body_axis), atol=1e-12), step.name
            checked += 1
        prev = step
    return checked


@pytest.mark.parametrize("name", ["ten-step", "ten-step-fast-spin", "twenty-four-position", "static-noise"])
@pytest.mark.parametrize("mounting_index", range(len(MOUNTINGS)))
def test_shipped_procedures_compile_and_rotations_are_realised(name: str, mounting_index: int) -> None:
    mounting = MOUNTINGS[mounting_index]
    comp = _compile(name, mounting=mounting)
    assert [s.index for s in comp.steps] == list(range(len(comp.steps)))
    assert len({s.name for s in comp.steps}) == len(comp.steps)
    assert all(s.line is not None for s in comp.steps)
    n = _check_rotations(comp, mounting)
    assert n == sum(1 for s in comp.steps if s.kind == "spin" or (s.kind == "move" and s.body_axis))
    assert comp.estimated_duration(SIM_LIMITS) > comp.acquisition_time() > 0


def test_ten_step_structure_and_spec_attitudes() -> None:
    comp = _compile("ten-step")
    for group, (words, ref_axis) in SPEC_BASES.items():
        steps = [s for s in comp.steps if s.group == group]
        holds = [s for s in steps if s.kind == "hold"]
        spins = [s for s in steps if s.kind == "spin"]
        assert len(holds) == 8 and len(spins) == 1
        assert holds[0].name == f"{group}/hold" and steps[0].name == f"{group}/orient"
        c_base = body_to_nav(np.asarray(holds[0].angles))
        assert np.allclose(c_base, _c(words), atol=1e-12)
        # the 8 positions are the base turned by k·45° about the reference body axis
        for k, h in enumerate(holds):
            expect = _c(words) @ Rotation.from_rotvec(k * math.pi / 4 * BODY[ref_axis]).as_matrix()
            assert np.allclose(body_to_nav(np.asarray(h.angles)), expect, atol=1e-12), h.name
        assert spins[0].body_axis == f"+{ref_axis}"
        assert abs(spins[0].rate) == pytest.approx(1.6 * D)
        assert spins[0].duration * abs(spins[0].rate) >= 2 * math.pi * (1 - 1e-12)
    # worked example of the task: gimbal angles and gimbals (identity mounting)
    orient = {s.group: s for s in comp.steps if s.name.endswith("/orient")}
    assert np.allclose(orient["A"].angles, (0, 0, 0), atol=1e-12)
    assert np.allclose(orient["B"].angles, (-90 * D, -90 * D, 0), atol=1e-12)
    assert np.allclose(orient["C"].angles, (90 * D, 0, 90 * D), atol=1e-12)
    gimbal = {s.group: s.axis for s in comp.steps if s.kind == "spin"}
    assert gimbal == {"A": 2, "B": 1, "C": 1}
    # steps accumulate, unwrapped, on that gimbal
    b_steps = [s for s in comp.steps if s.group == "B" and s.kind == "move" and s.body_axis]
    assert [round(s.angles[1] / D, 9) for s in b_steps] == [-45, 0, 45, 90, 135, 180, 225]
    assert comp.steps[0].kind == "warmup" and np.allclose(comp.steps[0].angles, (0, 0, 0))


def test_fast_spin_both_directions_and_rates() -> None:
    comp = _compile("ten-step-fast-spin")
    spins = [s for s in comp.steps if s.kind == "spin"]
    assert len(spins) == 6
    for a, b in zip(spins[::2], spins[1::2], strict=True):
        assert a.rate == -b.rate and abs(a.rate) >= 30 * D and a.name.endswith("spin+") and b.name.endswith("spin-")
        assert a.duration * abs(a.rate) >= 2 * 2 * math.pi  # several revolutions


def test_twenty_four_positions_are_the_cube_group() -> None:
    comp = _compile("twenty-four-position")
    holds = [s for s in comp.steps if s.kind == "hold"]
    assert len(holds) == 24
    mats = [body_to_nav(np.asarray(h.angles)) for h in holds]
    keys = set()
    for m in mats:
        assert np.allclose(m, np.round(m), atol=1e-12) and np.isclose(np.linalg.det(m), 1.0)
        keys.add(tuple(np.round(m).astype(int).ravel()))
    assert len(keys) == 24  # all distinct: the whole rotation group of the cube
    up = [tuple(np.round(m[2]).astype(int)) for m in mats]  # Up in body coordinates
    for axis in range(3):
        for sign in (1, -1):
            v = [0, 0, 0]
            v[axis] = sign
            assert up.count(tuple(v)) == 4
    assert not any(s.kind == "spin" for s in comp.steps)


def test_position_limit_violation_names_step_and_line() -> None:
    limited = (SIM_LIMITS[0], replace(SIM_LIMITS[1], position_min=-100 * D, position_max=100 * D), SIM_LIMITS[2])
    with pytest.raises(ConfigError) as info:
        _compile("ten-step", limits=limited)
    err = info.value
    text = load_procedure(resolve_procedure("ten-step")).text.splitlines()
    assert "step_rotate: {axis: x" in text[err.line - 1]
    assert "step 'B/step-5'" in str(err) and "middle gimbal would go to 135.000°" in str(err)
    assert "allowed" in str(err)


def test_rate_above_limit_names_step_and_line() -> None:
    slow = (SIM_LIMITS[0], SIM_LIMITS[1], replace(SIM_LIMITS[2], rate_max=20 * D))
    with pytest.raises(ConfigError) as info:
        _compile("ten-step-fast-spin", limits=slow)
    err = info.value
    assert "step 'A/spin+'" in str(err) and "inner gimbal" in str(err) and "|rate_dps| <= 20" in str(err)
    text = load_procedure(resolve_procedure("ten-step-fast-spin")).text.splitlines()
    assert "spin: {axis: y, rate_dps: 60" in text[err.line - 1]


def test_unreachable_attitude() -> None:
    tight = (
        replace(SIM_LIMITS[0], position_min=-10 * D, position_max=10 * D),
        replace(SIM_LIMITS[1], position_min=-10 * D, position_max=10 * D),
        SIM_LIMITS[2],
    )
    with pytest.raises(ConfigError) as info:
        _text(
            """
            name: t
            steps:
              - orient: {x: East, y: North, z: Up}
              - hold: {duration_s: 1}
              - orient: {x: Down, y: West, z: North}
            """,
            limits=tight,
        )
    assert (
        info.value.line == 5
        and "step 'orient#2'" in str(info.value)
        and "outside the table's limits" in str(info.value)
    )


def test_spin_on_limited_axis_is_refused() -> None:
    limited = (SIM_LIMITS[0], SIM_LIMITS[1], replace(SIM_LIMITS[2], position_min=-200 * D, position_max=200 * D))
    text = """
        name: t
        steps:
          - orient: {x: East, y: North, z: Up}
          - spin: {axis: y, rate_dps: 5, revolutions: 1}
        """
    with pytest.raises(ConfigError, match="spin only on a continuous axis") as info:
        _text(text, limits=limited)
    assert info.value.line == 4 and "step 'spin+'" in str(info.value)
    _text(text.replace("revolutions: 1", "duration_s: 10"), limits=limited)  # 50° + ramps: fits


def test_body_axis_not_aligned() -> None:
    with pytest.raises(ConfigError) as info:
        _text(
            """
            name: t
            steps:
              - orient: {x: East, y: North, z: Up}
              - step_rotate: {axis: y, angle_deg: 45, count: 1, hold_s: 1}
              - spin: {axis: x, rate_dps: 5, revolutions: 1}
            """
        )
    assert info.value.line == 5
    assert "body axis x is not aligned with any gimbal axis at attitude" in str(info.value)


def test_attitude_unknown_after_spin_and_before_orient() -> None:
    with pytest.raises(ConfigError, match="after a spin") as info:
        _text(
            """
            name: t
            steps:
              - orient: {x: East, y: North, z: Up}
              - spin: {axis: z, rate_dps: 5, revolutions: 1}
              - hold: {duration_s: 1}
            """
        )
    assert info.value.line == 5
    with pytest.raises(ConfigError, match="needs a known attitude"):
        _text("name: t\nsteps:\n  - hold: {duration_s: 1}\n")
    comp = _text("name: t\nsteps:\n  - warmup: {duration_s: 5}\n  - orient: {x: East, y: North}\n")
    assert comp.steps[0].angles is None  # warm-up where the table happens to be


def test_lock_family_is_searched_for_an_aligned_gimbal() -> None:
    # y Up puts the inner axis vertical (gimbal lock); a rotation about body x needs the middle gimbal along x,
    # which only some members of the lock family provide.
    comp = _text(
        """
        name: t
        steps:
          - orient: {x: North, y: Up, z: East}
          - step_rotate: {axis: x, angle_deg: 30, count: 2, hold_s: 1}
        """
    )
    assert _check_rotations(comp) == 2
    assert comp.steps[1].axis == 1


def test_estimated_duration_by_hand() -> None:
    comp = _text(
        """
        name: t
        defaults: {settle_s: 2}
        steps:
          - orient: {angles_deg: [0, 0, 0]}
          - hold: {duration_s: 10}
          - step_rotate: {axis: y, angle_deg: 90, count: 1, hold_s: 5}
          - spin: {axis: y, rate_dps: 40, duration_s: 9, settle_s: 1}
          - orient: {angles_deg: [0, 0, 0]}
        """
    )
    inner = SIM_LIMITS[2]
    move90 = move_time((0, 0, 0), (0, 0, math.pi / 2), SIM_LIMITS)
    assert move90 == pytest.approx(2 * math.sqrt((math.pi / 2) / inner.accel_max))  # triangular at 200 °/s²
    ramp = 40 * D / inner.accel_max
    travel = 40 * D * (1 + 9) + 40 * D * ramp  # settle + counted + both ramps
    back = move_time((0, 0, math.pi / 2 + travel), (0, 0, 0), SIM_LIMITS)
    expect = (2 + 10) + move90 + (2 + 5) + (2 * ramp + 1 + 9) + back
    assert comp.estimated_duration(SIM_LIMITS) == pytest.approx(expect, rel=1e-12)
    assert [s.name for s in comp.steps] == ["orient", "hold", "step-1", "hold-1", "spin+", "orient#2"]


def test_repeat_and_group_names_are_unique() -> None:
    comp = _text(
        """
        name: t
        steps:
          - group:
              name: A
              steps:
                - orient: {x: East, y: North}
                - repeat:
                    count: 2
                    steps:
                      - hold: {duration_s: 1}
                      - spin: {axis: z, rate_dps: 10, direction: both, revolutions: 1}
                      - orient: {x: East, y: North}
          - note: done
        """
    )
    names = [s.name for s in comp.steps]
    assert names == [
        "A/orient", "A/hold@1", "A/spin+@1", "A/spin-@1", "A/orient@1",
        "A/hold@2", "A/spin+@2", "A/spin-@2", "A/orient@2", "note",
    ]  # fmt: skip
    assert comp.steps[2].axis == 0 and comp.steps[-1].group == ""


def test_summary_is_readable() -> None:
    comp = _compile("ten-step")
    text = comp.summary(SIM_LIMITS)
    assert "x South, y Down, z East" in text and "spin about body +y at 1.6 °/s" in text
    assert "estimated duration" in text
    assert len(text.splitlines()) == len(comp.steps) + 5

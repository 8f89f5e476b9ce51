"""Procedure files: schema validation, SI conversion, parameters, and errors that name file and line."""

from __future__ import annotations

import math
import textwrap

import pytest

from core.yaml_source import ConfigError
from procedures.loader import (
    GroupSpec,
    HoldSpec,
    OrientSpec,
    SpinSpec,
    StepRotateSpec,
    WarmupSpec,
    load_procedure,
    load_procedure_text,
)
from procedures.paths import PACKAGE_PROCEDURES, resolve_procedure, shipped_procedures

SHIPPED = ["static-noise", "ten-step", "ten-step-fast-spin", "twenty-four-position"]


def _load(text: str, **kw):
    return load_procedure_text(textwrap.dedent(text).lstrip("\n"), "p.yaml", **kw)


def _error(text: str, **kw) -> ConfigError:
    with pytest.raises(ConfigError) as info:
        _load(text, **kw)
    return info.value


def test_shipped_procedures_are_listed_and_load() -> None:
    assert set(SHIPPED) <= set(shipped_procedures())
    for name in SHIPPED:
        for spelling in (name, f"{name}.yaml"):
            path = resolve_procedure(spelling)
            assert path.parent == PACKAGE_PROCEDURES
        proc = load_procedure(resolve_procedure(name))
        assert proc.name == name
        assert len(proc.sha256) == 64 and proc.text.startswith("#")


def test_units_are_si_after_loading() -> None:
    proc = _load(
        """
        name: t
        defaults: {hold_s: 30}
        steps:
          - orient: {x: East, z: Up}
          - step_rotate: {axis: -y, angle_deg: 45, count: 2}
          - spin: {axis: y, rate_dps: 10, direction: both, revolutions: 2}
        """
    )
    orient, rot, spin = proc.steps
    assert isinstance(orient, OrientSpec) and orient.attitude.directions is not None
    assert orient.attitude.directions["y"] == (0, 1, 0)  # completed right-handed: z × x = y
    assert isinstance(rot, StepRotateSpec)
    assert rot.axis == "-y" and rot.angle == pytest.approx(math.pi / 4) and rot.hold == 30.0 and rot.count == 2
    assert isinstance(spin, SpinSpec)
    assert spin.axis == "+y" and spin.rates == pytest.approx((math.radians(10), -math.radians(10)))
    assert spin.revolutions == 2 and spin.duration is None
    assert [s.line for s in proc.steps] == [4, 5, 6]


def test_groups_repeat_and_angles() -> None:
    proc = _load(
        """
        name: t
        steps:
          - warmup: {duration_s: 10, at: {angles_deg: [10, -20, 30]}}
          - group:
              name: A
              steps:
                - repeat:
                    count: 2
                    steps:
                      - hold: {duration_s: 5}
        """
    )
    warm, group = proc.steps
    assert isinstance(warm, WarmupSpec) and warm.at is not None
    assert warm.at.angles == pytest.approx(tuple(math.radians(a) for a in (10, -20, 30)))
    assert isinstance(group, GroupSpec) and group.group == "A"
    assert isinstance(group.steps[0].steps[0], HoldSpec)  # type: ignore[attr-defined]


def test_yaml_syntax_error_names_the_line() -> None:
    err = _error(
        """
        name: t
        steps:
          - hold: {duration_s: 5
          - hold: {duration_s: 5}
        """
    )
    assert err.file == "p.yaml" and err.line in (3, 4)
    assert "YAML syntax error" in str(err)


def test_unknown_step_kind() -> None:
    err = _error(
        """
        name: t
        steps:
          - hold: {duration_s: 5}
          - wobble: {duration_s: 5}
        """
    )
    assert err.line == 4
    assert "unknown step kind 'wobble'" in str(err) and "step_rotate" in str(err)


def test_wrong_type_and_unknown_key_name_the_step_and_line() -> None:
    text = """
        name: t
        steps:
          - orient: {x: East, y: North, z: Up}
          - group:
              name: A
              steps:
                - step_rotate:
                    axis: y
                    angle_deg: forty-five
                    count: 7
                    hold_s: 10
        """
    err = _error(text)
    assert err.line == 9
    assert str(err).startswith("p.yaml:9: step 'A/step_rotate': angle_deg: expected")
    err = _error(text.replace("angle_deg: forty-five", "angle_deg: 45\n                    speed: 3"))
    assert err.line == 10 and "unknown key 'speed'" in str(err) and "allowed here" in str(err)


@pytest.mark.parametrize(
    ("body", "line", "fragment"),
    [
        ("- hold: {}", 4, "duration_s is required"),
        ("- spin: {axis: y, rate_dps: 5}", 4, "exactly one of revolutions or duration_s"),
        ("- spin: {axis: q, rate_dps: 5, revolutions: 1}", 4, "axis: 'q' is not allowed"),
        ("- spin: {axis: y, rate_dps: -5, direction: both, revolutions: 1}", 4, "must be positive"),
        ("- spin: {axis: y, rate_dps: 5, direction: up, revolutions: 1}", 4, "choose positive, negative or both"),
        ("- orient: {x: East, y: North, z: Down}", 4, "left-handed"),
        ("- orient: {x: East, y: West}", 4, "same line"),
        ("- orient: {x: Sideways, y: West}", 4, "not a direction"),
        ("- orient: {z: Up}", 4, "at least two body axes"),
        ("- step_rotate: {axis: y, angle_deg: 45, count: 2.5, hold_s: 1}", 4, "whole number"),
        ("- repeat: {count: 2}", 4, "steps is required"),
        ("- group: {steps: [{note: hi}]}", 4, "name is required"),
        ("- note: 5", 4, "expected text"),
        ("- hold: 5", 4, "expected a mapping"),
        ("- repeat: {count: 20000, steps: [{note: hi}]}", 4, "must be <= 10000"),
    ],
)
def test_bad_steps(body: str, line: int, fragment: str) -> None:
    err = _error(f"name: t\nsteps:\n  - orient: {{x: East, y: North}}\n  {body}\n")
    assert err.line == line, str(err)
    assert fragment in str(err)


def test_top_level_errors() -> None:
    assert "unknown key 'stpes'" in str(_error("name: t\nstpes: []\n"))
    assert "name is required" in str(_error("steps:\n  - note: hi\n"))
    assert "the list is empty" in str(_error("name: t\nsteps: []\n"))
    err = _error("name: t\ndefaults: {hold: 3}\nsteps:\n  - note: hi\n")
    assert err.line == 2 and "allowed here: settle_s, hold_s, spin_settle_s" in str(err)


def test_parameters_and_overrides() -> None:
    text = """
        name: t
        parameters: {duration_s: 7200}
        steps:
          - orient: {x: East, y: North}
          - hold: {duration_s: $duration_s}
        """
    assert _load(text).steps[1].duration == 7200.0  # type: ignore[attr-defined]
    assert _load(text, overrides={"duration_s": 60}).steps[1].duration == 60.0  # type: ignore[attr-defined]
    err = _error(text, overrides={"duration": 60})
    assert "unknown parameter 'duration'" in str(err) and "duration_s" in str(err)
    err = _error(text.replace("$duration_s", "$length_s"))
    assert err.line == 5 and "unknown parameter '$length_s'" in str(err)


def test_missing_file_is_a_config_error(tmp_path) -> None:
    with pytest.raises(ConfigError, match="file not found"):
        load_procedure(tmp_path / "nope.yaml")
    with pytest.raises(ConfigError, match="shipped procedures: .*ten-step"):
        resolve_procedure("no-such-procedure")

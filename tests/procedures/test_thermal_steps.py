"""The chamber steps soak and ramp: parsed with line-numbered errors, checked against the bench's chamber before
anything moves, the ramp's table sequence repeated to cover the ramp; the shipped thermal procedure compiles."""

from __future__ import annotations

import math

import pytest

from analysis.units import celsius_to_kelvin as C
from core.yaml_source import ConfigError
from drivers.protocols import AxisLimits
from procedures.compiler import compile_procedure
from procedures.loader import load_procedure, load_procedure_text
from procedures.steps import Ramp, Soak
from tests import REPO_ROOT

LIMITS = tuple(AxisLimits(rate_max=math.radians(300), accel_max=math.radians(100)) for _ in range(3))
CHAMBER = (C(-40.0), C(150.0))


def text(steps: str) -> str:
    return f"name: t\ndescription: x\nversion: 1\nsteps:\n{steps}"


def test_soak_parses_in_si_with_defaults():
    p = load_procedure_text(text("  - soak: {setpoint_c: -20, dwell_s: 300}\n"))
    c = compile_procedure(p, limits=LIMITS, chamber=CHAMBER)
    (s,) = c.steps
    assert isinstance(s, Soak) and not s.acquires
    assert s.setpoint == pytest.approx(C(-20.0)) and s.target == s.setpoint
    assert s.tolerance == 0.5 and s.rate_limit == pytest.approx(0.1 / 60) and s.dwell == 300.0


@pytest.mark.parametrize(
    ("body", "message"),
    [
        ("{dwell_s: 300}", "setpoint_c is required"),
        ("{setpoint_c: 20, tolerance: 1}", "unknown key 'tolerance'"),
        ("{setpoint_c: 20, tolerance_k: -1}", "must be > 0"),
        ("{setpoint_c: 500}", "must be <= 300"),
    ],
)
def test_soak_errors_name_the_line_and_the_fix(body, message):
    with pytest.raises(ConfigError, match=message) as e:
        load_procedure_text(text(f"  - note: first\n  - soak: {body}\n"))
    assert ":6:" in str(e.value)


def test_no_chamber_or_outside_its_limits_is_refused_before_anything_moves():
    p = load_procedure_text(text("  - soak: {setpoint_c: -30}\n"))
    with pytest.raises(ConfigError, match="needs a temperature chamber"):
        compile_procedure(p, limits=LIMITS)
    with pytest.raises(ConfigError, match=r"outside the chamber's set-point limits \[-20, 60\]"):
        compile_procedure(p, limits=LIMITS, chamber=(C(-20.0), C(60.0)))


def test_ramp_soaks_first_then_repeats_the_sequence_over_the_ramp():
    ramp = (
        "  - ramp:\n      from_c: 0\n      to_c: 20\n      rate_k_per_min: 0.5\n      steps:\n"
        "        - orient: {x: East, y: North, z: Up}\n        - hold: {duration_s: 60}\n"
        "        - orient: {x: West, y: South, z: Up}\n        - hold: {duration_s: 60}\n"
    )
    c = compile_procedure(load_procedure_text(text(ramp)), limits=LIMITS, chamber=CHAMBER, settle=0.0)
    assert isinstance(c.steps[0], Soak) and c.steps[0].setpoint == pytest.approx(C(0.0))
    r = c.steps[1]
    assert isinstance(r, Ramp) and r.ramp_time == pytest.approx(20 / 0.5 * 60)
    holds = [s for s in c.steps if s.kind == "hold"]
    seq_time = sum(s.bench_time(LIMITS, None)[0] for s in c.steps[2:6])  # one repetition (moves from unknown: 0)
    assert len(holds) // 2 >= math.ceil(r.ramp_time / (seq_time + 2 * 4.0))  # at least enough repetitions
    assert sum(s.duration for s in holds) >= r.ramp_time * 0.5


def test_shipped_thermal_procedure_compiles_with_a_soak_per_plateau():
    p = load_procedure(REPO_ROOT / "procedures" / "thermal-plateaus.yaml")
    c = compile_procedure(p, limits=LIMITS, chamber=CHAMBER)
    soaks = [s for s in c.steps if isinstance(s, Soak)]
    assert [round(s.setpoint - 273.15) for s in soaks] == [-20, 0, 20, 40, 60]
    assert sum(1 for s in c.steps if s.kind == "spin") == 5 * 6

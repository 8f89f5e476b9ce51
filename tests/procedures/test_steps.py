"""Typed compiled steps: every kind is a class that knows its time, its commands and whether it acquires."""

from __future__ import annotations

import math

import numpy as np
import pytest

from drivers.protocols import AxisLimits
from procedures.compiler import compile_procedure
from procedures.loader import load_procedure
from procedures.paths import resolve_procedure, shipped_procedures
from procedures.steps import (
    Hold,
    Move,
    Note,
    Ramp,
    Soak,
    Spin,
    Step,
    Warmup,
    limit_problems,
    move_time,
    trapezoid_time,
)

D = math.pi / 180
LIMITS = (
    AxisLimits(rate_max=100 * D, accel_max=50 * D),
    AxisLimits(rate_max=200 * D, accel_max=100 * D, position_min=-90 * D, position_max=90 * D),
    AxisLimits(rate_max=400 * D, accel_max=200 * D),
)
CONTINUOUS = tuple(AxisLimits(rate_max=lim.rate_max, accel_max=lim.accel_max) for lim in LIMITS)
TYPES = (Move, Warmup, Hold, Spin, Note, Soak, Ramp)
CHAMBER = (273.15 - 40.0, 273.15 + 150.0)  # set-point limits, K (thermal procedures need a chamber)


@pytest.mark.parametrize("name", shipped_procedures())
def test_shipped_procedures_compile_to_typed_steps(name: str) -> None:
    # against a table that can run every shipped procedure: the rate-transfer test needs 300 °/s on the outer axis
    limits = CONTINUOUS
    if name == "gyro-rate-transfer":
        limits = (AxisLimits(rate_max=300 * D, accel_max=80 * D), *CONTINUOUS[1:])
    comp = compile_procedure(load_procedure(resolve_procedure(name)), limits=limits, chamber=CHAMBER)
    for s in comp.steps:
        assert type(s) in TYPES
        assert s.acquires == isinstance(s, (Warmup, Hold, Spin))
        assert s.acquisition_time == (s.duration if s.acquires else 0.0)
        if isinstance(s, Spin):
            assert s.commanded_rates() == ((s.axis, s.rate),) and s.angles is None
        else:
            assert s.commanded_rates() == ()
        if isinstance(s, (Move, Hold)):
            assert s.commanded_positions() == (s.angles,)
    assert comp.acquisition_time() == pytest.approx(sum(s.duration for s in comp.steps if s.acquires))
    assert limit_problems(comp.steps, limits) == []
    # the summary shows every kind with its own words
    text = comp.summary(limits)
    assert all(f" {s.kind} " in text for s in comp.steps)


def test_kinds_are_distinct_and_named() -> None:
    assert len({t.kind for t in TYPES}) == len(TYPES)
    assert all(t.kind for t in TYPES) and not Step.kind


def test_required_fields_are_required() -> None:
    with pytest.raises(TypeError):
        Spin(index=0, name="s", rate=1.0)  # type: ignore[call-arg]  # no axis
    with pytest.raises(TypeError):
        Hold(index=0, name="h", duration=1.0)  # type: ignore[call-arg]  # no attitude
    with pytest.raises(TypeError):
        Move(0, "m", angles=(0.0, 0.0, 0.0))  # type: ignore[misc]  # keywords only


def test_bench_time_of_each_kind_from_the_profiles() -> None:
    start = np.zeros(3)
    hold = Hold(index=0, name="h", angles=(0.0, 0.0, 90 * D), duration=10.0, settle=2.0)
    t, end = hold.bench_time(LIMITS, start)
    assert t == pytest.approx(trapezoid_time(90 * D, 400 * D, 200 * D) + 12.0)
    assert np.allclose(end, (0, 0, 90 * D))
    spin = Spin(index=1, name="s", axis=0, rate=-20 * D, duration=18.0, settle=1.0)
    t, end2 = spin.bench_time(LIMITS, end)
    ramp = 20 / 50
    assert t == pytest.approx(2 * ramp + 1.0 + 18.0)
    assert end2[0] == pytest.approx(-(20 * D) ** 2 / (50 * D) - 20 * D * 19.0)
    note = Note(index=2, name="n", text="hi")
    assert note.bench_time(LIMITS, end2) == (0.0, end2)
    warm = Warmup(index=3, name="w", duration=5.0, settle=1.0)  # at the unknown initial attitude
    assert warm.bench_time(LIMITS, None) == (6.0, None)
    assert move_time((0, 0, 0), (0, 0, 0), LIMITS) == 0.0


def test_limit_problems_name_step_axis_and_limit() -> None:
    steps = [
        Move(index=0, name="too-far", angles=(0.0, 95 * D, 0.0)),
        Spin(index=1, name="too-fast", axis=2, rate=-401 * D, duration=1.0),
        Hold(index=2, name="fine", angles=(0.0, 90 * D, 0.0), duration=1.0),
    ]
    problems = limit_problems(steps, LIMITS)
    assert len(problems) == 2
    assert "'too-far'" in problems[0] and "middle" in problems[0] and "[-90°, 90°]" in problems[0]
    assert "'too-fast'" in problems[1] and "400.000 °/s" in problems[1]


def test_rate_transfer_on_a_slower_table_is_refused_before_motion_naming_the_step() -> None:
    from core.yaml_source import ConfigError

    with pytest.raises(ConfigError, match=r"gyro-rate-transfer.yaml:\d+: step 'X/spin\+#6': spin rate 300 °/s"):
        compile_procedure(load_procedure(resolve_procedure("gyro-rate-transfer")), limits=CONTINUOUS, chamber=CHAMBER)

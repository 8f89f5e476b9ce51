"""AxisLimits: the one answer to "is this position / rate / acceleration allowed?", one tolerance for all."""

from __future__ import annotations

import math

import numpy as np
import pytest

from drivers.protocols import LIMIT_TOLERANCE, AxisLimits, TableError, check_angles, check_spin
from procedures.steps import Hold, Spin, limit_problems
from tests.drivers.wire_support import LIMITS, make_world

D = math.pi / 180


def test_position_rate_acceleration_with_one_tolerance() -> None:
    lim = AxisLimits(rate_max=2.0, accel_max=3.0, position_min=-1.5, position_max=1.5)
    tol = LIMIT_TOLERANCE * 1.5
    assert lim.allows_position(1.5 + 0.5 * tol) and not lim.allows_position(1.5 + 2 * tol)
    assert lim.allows_position(-1.5 - 0.5 * tol) and not lim.allows_position(-1.5 - 2 * tol)
    assert lim.allows_rate(-2.0 * (1 + 0.5 * LIMIT_TOLERANCE)) and not lim.allows_rate(2.0 * (1 + 2 * LIMIT_TOLERANCE))
    assert lim.allows_acceleration(3.0) and not lim.allows_acceleration(-3.0 * (1 + 2 * LIMIT_TOLERANCE))
    for bad in (math.nan, math.inf, -math.inf):
        assert not lim.allows_position(bad) and not lim.allows_rate(bad) and not lim.allows_acceleration(bad)
    free = AxisLimits(rate_max=1.0, accel_max=1.0)
    assert free.continuous and free.position_bounds() == (-math.inf, math.inf)
    assert free.allows_position(1e9) and free.allows_demand(-20 * math.pi) and not free.allows_demand(1e9)
    assert free.position_range_text().startswith("continuous")
    assert lim.position_range_text() == f"[{math.degrees(-1.5):g}°, {math.degrees(1.5):g}°]"


@pytest.mark.parametrize("excess", [0.5, 2.0])
def test_compiler_runner_driver_and_world_agree_at_the_edge(excess: float) -> None:
    """Just inside the tolerance everyone accepts; just outside everyone refuses (no 'compiles but the table
    refuses')."""
    mid = LIMITS[1]
    assert mid.position_max is not None
    edge = mid.position_max + excess * LIMIT_TOLERANCE * max(1.0, abs(mid.position_max))
    rate = LIMITS[2].rate_max * (1 + excess * LIMIT_TOLERANCE)
    allowed = excess < 1
    angles = (0.0, edge, 0.0)
    assert (limit_problems([Hold(index=0, name="h", angles=angles, duration=1.0)], LIMITS) == []) == allowed
    assert (limit_problems([Spin(index=0, name="s", axis=2, rate=rate, duration=1.0)], LIMITS) == []) == allowed

    def accepted(fn) -> bool:
        try:
            fn()
        except TableError:
            return False
        return True

    assert accepted(lambda: check_angles(angles, LIMITS)) == allowed
    assert accepted(lambda: check_spin(2, rate, LIMITS)) == allowed
    world = make_world(0)
    assert accepted(lambda: world.command_position(np.array(angles))) == allowed
    assert accepted(lambda: world.command_rate(2, rate)) == allowed

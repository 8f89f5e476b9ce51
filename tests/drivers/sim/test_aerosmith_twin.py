"""The Ideal Aerosmith driver against its simulated twin on the one simulated world: spin, at rate, stop, home."""

from __future__ import annotations

import math

import pytest

from drivers.aerosmith import AerosmithSettings, AerosmithTable
from drivers.protocols import AxisLimits, TableStatus
from drivers.sim.aerosmith_controller import AerosmithController
from drivers.sim.config import SimConfig, TableModel
from drivers.sim.world import SimulatedWorld

R = math.radians
ABSENT = AxisLimits.absent_axis()
LIMITS = (ABSENT, ABSENT, AxisLimits(rate_max=R(360), accel_max=R(80)))


def test_driver_and_twin_on_the_world():
    world = SimulatedWorld(SimConfig(table=TableModel(limits=LIMITS)), 1)
    ctrl = AerosmithController(world, AerosmithSettings())
    t = AerosmithTable(ctrl.stream(), LIMITS, clock=lambda: world.time)
    t.spin(2, R(30))
    world.produce(1000)
    s = t.read_state()
    assert s.status & TableStatus.AT_RATE and math.degrees(s.rates[2]) == pytest.approx(30, abs=1e-3)
    t.stop()
    world.produce(1000)
    assert abs(t.read_state().rates[2]) < R(0.01)
    t.move_to([0.0, 0.0, 0.0])
    world.produce(5000)
    s = t.read_state()
    assert s.status & TableStatus.IN_POSITION and abs(math.remainder(s.angles[2], 2 * math.pi)) < R(0.01)
    assert ctrl.handle("JOG999").startswith("ERROR")  # the controller checks its limits too
    t.close()

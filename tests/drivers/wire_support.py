"""Shared helpers for the wire-transport tests: the table limits and a simulated world to serve."""

from __future__ import annotations

import math

from drivers.protocols import AxisLimits
from drivers.sim.config import SimConfig, TableModel
from drivers.sim.world import SimulatedWorld

LIMITS = (
    AxisLimits(rate_max=math.radians(300), accel_max=math.radians(100)),
    AxisLimits(rate_max=math.radians(200), accel_max=math.radians(100), position_min=-math.pi, position_max=math.pi),
    AxisLimits(rate_max=math.radians(200), accel_max=math.radians(100)),
)


def make_world(seed: int = 0) -> SimulatedWorld:
    """The simulated world with default truth and the LIMITS above."""
    return SimulatedWorld(SimConfig(table=TableModel(limits=LIMITS)), seed)

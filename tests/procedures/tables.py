"""Table limits the procedure tests compile against (SI): three continuous axes, like the simulated bench's
(though slower: these numbers are the tests' own, so the tests do not move when benches/sim.yaml does)."""

from __future__ import annotations

import math

from drivers.protocols import AxisLimits

D = math.pi / 180
"""One degree, rad."""

SIM_LIMITS = (
    AxisLimits(rate_max=100 * D, accel_max=50 * D),
    AxisLimits(rate_max=200 * D, accel_max=100 * D),
    AxisLimits(rate_max=400 * D, accel_max=200 * D),
)

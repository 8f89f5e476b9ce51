"""A simulated thermal run: per-plateau estimates against the simulated truth at the plateau's temperature, and
(slow) the Monte Carlo of the thermal model over 20 seeds THROUGH THE RUNNER (RESULTS.md, section "thermal"):
coefficient recovery, BIC orders, and the residual bias and scale after compensation against the U the
certificate states."""

from __future__ import annotations

import numpy as np
import pytest

from analysis.thermal.soak import SoakCriterion
from analysis.units import celsius_to_kelvin as C
from benches.thermal.montecarlo import run_montecarlo
from benches.thermal.simrun import ThermalPlan, run_thermal
from benches.thermal.truth import thermal_sim_config, truth_polynomials
from drivers.sim.world import SimulatedWorld


def test_two_plateaus_estimate_the_truth_at_the_unit_temperature():
    cfg = thermal_sim_config(sample_rate=20.0, unit_time_constant=120.0)
    plan = ThermalPlan(
        plateaus=(C(0.0), C(40.0)),
        soak=SoakCriterion(tolerance=0.1, rate_limit=0.01 / 60, dwell=60.0, rate_window=60.0),
        hold=10.0,
    )
    run = run_thermal(SimulatedWorld(cfg, 11), plan, fit=False)
    truth = truth_polynomials(cfg)
    ref = cfg.thermal.reference
    z = []
    for pl in run.plateaus:
        expected = np.array([np.polyval(np.asarray(c)[::-1], pl.temperature - ref) for c in truth])
        z.append((pl.x - expected) / np.sqrt(np.diag(pl.covariance)))
        assert abs(pl.rate) < 0.01 / 60
    z = np.concatenate(z)
    assert np.mean(np.abs(z) > 2.0) <= 0.15  # 60 coefficients: ~3 expected beyond 2u
    assert np.max(np.abs(z)) < 5.0
    assert run.plateaus[0].direction == "cooling" and run.plateaus[1].direction == "heating"
    assert run.soak_seconds[1] > np.log(40 / 0.1) * 120.0  # at least the unit's lag after a 40 K step


@pytest.mark.slow
def test_montecarlo_recovers_every_coefficient_and_the_orders():
    mc = run_montecarlo(range(20))
    for cls, (outside, hit, residual, _) in mc.fractions().items():
        if cls in ("bias", "scale", "misalignment"):  # the temperature-dependent classes, both triads
            assert 0.02 <= outside <= 0.09, (cls, outside)
        else:  # quadratic and size effect (60 coefficients each): too few for a lower bound
            assert outside <= 0.09, (cls, outside)
        assert hit >= 0.90, (cls, hit)
        assert residual <= 0.10, (cls, residual)
    # after compensation (what 'tablebench correct' applies), the residual bias and scale of both triads are
    # within the U(k = 2) the certificate states at each temperature of its table — as a 95 % interval: no
    # more than 9 % of the checks beyond it per class (2-9 %, as for the coefficients)
    comp = mc.compensated_outside()
    assert set(comp) == {"accel bias", "accel scale", "gyro bias", "gyro scale"}
    for cls, (outside, n) in comp.items():
        assert n >= 20 * 3 * 9 and outside <= 0.09, (cls, outside)

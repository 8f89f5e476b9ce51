"""The simulated unit used by the thermal Monte Carlo, the speed benchmark and the shipped thermal bench:
a tactical-grade IMU whose biases, scale factors and misalignments move with its own temperature
(orders 0–3; magnitudes typical of MEMS/quartz units, PX4 fits offsets up to third order).

Every coefficient is well above the per-plateau uncertainty of the calibration sequence, so the model order
is identifiable from 5 plateaus; the quadratic and size-effect terms do not depend on temperature (order 0).
"""

from __future__ import annotations

import numpy as np

from analysis.identification.model import PARAM_NAMES
from analysis.units import ARCSEC, DEG_PER_HOUR, DEG_PER_SQRT_HOUR, MM, PPM, UG, UG_PER_G2, celsius_to_kelvin
from drivers.sim.config import AccelTruth, GyroTruth, NoiseTruth, SimConfig
from drivers.sim.thermal_config import ChamberSim, ThermalTruth, TriadThermal
from drivers.sim.world import SimulatedWorld

THERMAL_TRUTH = ThermalTruth(
    reference=celsius_to_kelvin(20.0),
    accel=TriadThermal(
        bias=((30 * UG, -20 * UG, 25 * UG), (0.3 * UG, -0.2 * UG, 0.25 * UG)),
        scale=((5 * PPM, -4 * PPM, 6 * PPM),),
        misalignment=(tuple(a * ARCSEC for a in (0.5, -0.4, 0.3, 0.6, -0.5, 0.4)),),
    ),
    gyro=TriadThermal(
        bias=(
            (0.05 * DEG_PER_HOUR, -0.04 * DEG_PER_HOUR, 0.03 * DEG_PER_HOUR),
            (1e-3 * DEG_PER_HOUR, 0.8e-3 * DEG_PER_HOUR, -1e-3 * DEG_PER_HOUR),
            (2e-5 * DEG_PER_HOUR, -2e-5 * DEG_PER_HOUR, 3e-5 * DEG_PER_HOUR),
        ),
        scale=((10 * PPM, -8 * PPM, 12 * PPM),),
        misalignment=(tuple(a * ARCSEC for a in (1.0, -0.8, 0.6, 1.2, -1.0, 0.8)),),
    ),
)
"""Temperature dependence of the simulated unit (T_ref = 20 °C)."""


def thermal_sim_config(sample_rate: float = 50.0, unit_time_constant: float = 300.0) -> SimConfig:
    """A simulated bench with a chamber around a temperature-dependent unit (white noise only)."""
    return SimConfig(
        sample_rate=sample_rate,
        accel=AccelTruth(
            bias=(100 * UG, -80 * UG, 120 * UG),
            scale=(200 * PPM, -150 * PPM, 250 * PPM),
            misalignment=tuple(a * ARCSEC for a in (30.0, -25.0, 20.0, 35.0, -30.0, 15.0)),  # type: ignore[arg-type]
            quadratic=(20 * UG_PER_G2, -15 * UG_PER_G2, 25 * UG_PER_G2),
            lever_arms=((30 * MM, 0.0, 0.0), (0.0, -28 * MM, 0.0), (0.0, 0.0, 32 * MM)),
        ),
        gyro=GyroTruth(
            bias=(0.5 * DEG_PER_HOUR, -0.3 * DEG_PER_HOUR, 0.4 * DEG_PER_HOUR),
            scale=(50 * PPM, -40 * PPM, 60 * PPM),
            misalignment=tuple(a * ARCSEC for a in (10.0, -8.0, 6.0, 12.0, -10.0, 8.0)),  # type: ignore[arg-type]
        ),
        accel_noise=NoiseTruth(white=(20 * UG,) * 3),
        gyro_noise=NoiseTruth(white=(0.01 * DEG_PER_SQRT_HOUR,) * 3),
        chamber=ChamberSim(unit_time_constant=unit_time_constant),
        thermal=THERMAL_TRUTH,
    )


def truth_polynomials(cfg: SimConfig) -> list[tuple[float, ...]]:
    """The simulated coefficients of every thermal-model parameter (``THERMAL_PARAM_NAMES`` order), in powers of
    (T − T_ref) with T_ref = the truth's reference, SI per K^k; trailing zero coefficients dropped (so the
    length − 1 is the simulated order). The size effect's (1 + S_i) factor is taken at T_ref (its temperature
    dependence, ~1e-4 relative over the range, is below what a plateau resolves)."""
    assert cfg.thermal is not None
    truth = SimulatedWorld(cfg, 0).truth()  # the whole unit's truth: take the accelerometer's 18 by name
    base = [float(truth[n]) for n in PARAM_NAMES]
    g = cfg.gyro
    base += [*g.bias, *g.scale, *g.misalignment]
    out: list[tuple[float, ...]] = []
    for p, b0 in enumerate(base):
        triad = cfg.thermal.accel if p < 18 else cfg.thermal.gyro
        q = p if p < 18 else p - 18
        bias, scale, mis, _ = triad.arrays()
        if q < 3:
            rows = bias[:, q]
        elif q < 6:
            rows = scale[:, q - 3]
        elif q < 12:
            rows = mis[:, q - 6]
        else:
            rows = np.zeros(0)
        coeffs = [float(b0), *[float(v) for v in rows]]
        while len(coeffs) > 1 and coeffs[-1] == 0.0:
            coeffs.pop()
        out.append(tuple(coeffs))
    return out

"""Configuration of the simulated chamber and of the unit's temperature-dependent truth, SI (K, s, K/s).

The chamber model (docs/methods/thermal.md, "the simulated chamber") is a modelling choice, not a vendor fact:
set-point path rate-limited, air second order on it, unit first order on the air.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from analysis.units import celsius_to_kelvin

Vec3 = tuple[float, float, float]


@dataclass(frozen=True)
class ChamberSim:
    """The simulated chamber.

    Attributes
    ----------
    ramp_up, ramp_down : float
        Largest rate of the effective set point, K/s (defaults 2.9 and 1.7 °C/min, an Espec SH-641's ratings).
    setpoint_min, setpoint_max : float
        The controller's own range, K (−40 … 150 °C); a write outside is refused.
    air_time_constant : float
        1/ω of the air's second-order response, s (60 s).
    air_damping : float
        ζ (0.7: a step overshoots by exp(−πζ/√(1−ζ²)) = 4.6 %).
    air_noise : float
        Standard deviation of the reported air temperature, K (0.05).
    unit_time_constant : float
        τ_u of the unit's first-order lag on the air, s (600 s).
    self_heating : float
        ΔT_self: the unit settles this much above the air, K (0).
    ambient : float
        Lab temperature: the air goes there when the chamber is stopped, and starts there, K (23 °C).
    step : float
        Integration step of the chamber model, s (1 s; exact for a set point held over a step).
    resolution : float
        Resolution of the reported temperatures, K (0.1 °C, as one decimal on the wire).
    """

    ramp_up: float = 2.9 / 60.0
    ramp_down: float = 1.7 / 60.0
    setpoint_min: float = celsius_to_kelvin(-40.0)
    setpoint_max: float = celsius_to_kelvin(150.0)
    air_time_constant: float = 60.0
    air_damping: float = 0.7
    air_noise: float = 0.05
    unit_time_constant: float = 600.0
    self_heating: float = 0.0
    ambient: float = celsius_to_kelvin(23.0)
    step: float = 1.0
    resolution: float = 0.1

    def __post_init__(self) -> None:
        for name in ("ramp_up", "ramp_down", "air_time_constant", "air_damping", "unit_time_constant", "step"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise ValueError(f"simulated chamber {name} must be > 0, got {v!r}")
        if not self.setpoint_min < self.setpoint_max:
            raise ValueError("simulated chamber setpoint_min must be below setpoint_max")


def _coeffs(rows: tuple[tuple[float, ...], ...], width: int, what: str) -> NDArray[np.float64]:
    a = np.asarray(rows, dtype=float).reshape(-1, width) if len(rows) else np.zeros((0, width))
    if not np.all(np.isfinite(a)):
        raise ValueError(f"thermal truth {what} must be finite")
    return a


@dataclass(frozen=True)
class TriadThermal:
    """Temperature dependence of one triad's errors: p(T) = p(T_ref) + Σ_{k≥1} p_k (T − T_ref)^k + p_Ṫ·Ṫ.

    Attributes
    ----------
    bias : tuple of rows (3,)
        Row k−1 = bias coefficients of (T − T_ref)^k, SI per K^k (m/s² or rad/s).
    scale : tuple of rows (3,)
        Row k−1 = scale-factor coefficients, 1/K^k.
    misalignment : tuple of rows (6,)
        Row k−1 = misalignment coefficients (the six τ of the model, order of ``MISALIGNMENT_PAIRS``), rad/K^k.
    bias_rate : (3,)
        Bias per unit rate of the unit's temperature, SI per K/s (the lag / hysteresis term).
    """

    bias: tuple[Vec3, ...] = ()
    scale: tuple[Vec3, ...] = ()
    misalignment: tuple[tuple[float, ...], ...] = ()
    bias_rate: Vec3 = (0.0, 0.0, 0.0)

    def arrays(self) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
        """(bias (k,3), scale (k,3), misalignment (k,6), bias_rate (3,)) as arrays."""
        return (
            _coeffs(self.bias, 3, "bias"),
            _coeffs(self.scale, 3, "scale"),
            _coeffs(self.misalignment, 6, "misalignment"),
            np.asarray(self.bias_rate, dtype=float),
        )


@dataclass(frozen=True)
class ThermalTruth:
    """The unit's temperature-dependent truth: the configured triad truth holds at ``reference``.

    Attributes
    ----------
    reference : float
        T_ref, K (default 23 °C).
    accel, gyro : TriadThermal
    """

    reference: float = celsius_to_kelvin(23.0)
    accel: TriadThermal = field(default_factory=TriadThermal)
    gyro: TriadThermal = field(default_factory=TriadThermal)

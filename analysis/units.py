"""Unit conversions at the boundary (YAML, CLI, certificates, plots), in one place.

Everything inside tablebench is SI: m/s², rad, rad/s, s, K. Display units appear only in YAML input,
command-line arguments, printed text, plots and certificates, and every conversion goes through the
constants and helpers here.

The conventional standard gravity ``G0 = 9.80665 m/s²`` is used for display units expressed in g (µg,
µg/g², ppm of g); it is *not* the local gravity of a bench (see ``drivers.sim.earth``).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike

G0: float = 9.80665
"""Standard gravity (m/s²), used only to express accelerations in g / µg for display."""

DEG: float = math.pi / 180.0
"""One degree in radians."""
ARCSEC: float = DEG / 3600.0
"""One arcsecond in radians."""
PPM: float = 1e-6
"""One part per million (dimensionless)."""
UG: float = 1e-6 * G0
"""One micro-g in m/s²."""
MG: float = 1e-3 * G0
"""One milli-g in m/s²."""
UG_PER_G2: float = UG / G0**2
"""One µg/g² in s²/m (quadratic coefficient: δf = d f², d in s²/m)."""
MM: float = 1e-3
"""One millimetre in metres."""
HOUR: float = 3600.0
"""One hour in seconds."""
DEG_PER_HOUR: float = DEG / HOUR
"""One °/h in rad/s."""
DEG_PER_SQRT_HOUR: float = DEG / math.sqrt(HOUR)
"""One °/√h (angle random walk) in rad/√s."""
UG_PER_SQRT_HZ: float = UG
"""One µg/√Hz (velocity random walk density) in m/s²/√Hz = m/s/√s."""
M_PER_S_PER_SQRT_HOUR: float = 1.0 / math.sqrt(HOUR)
"""One m/s/√h (velocity random walk) in m/s/√s."""
CELSIUS_ZERO: float = 273.15
"""0 °C in kelvin."""

FOOT: float = 0.3048
"""One international foot, m (KVH velocity increments in ft/s)."""

GAUSS: float = 1e-4
"""One gauss, T (magnetometer outputs)."""

# Display unit of each quantity kind: (unit label, SI value of one display unit).
DISPLAY_UNITS: dict[str, tuple[str, float]] = {
    "bias": ("µg", UG),
    "scale": ("ppm", PPM),
    "misalignment": ("arcsec", ARCSEC),
    "quadratic": ("µg/g²", UG_PER_G2),
    "size_effect": ("mm", MM),
    "angle": ("deg", DEG),
    "rate": ("deg/s", DEG),
    "acceleration": ("µg", UG),
    "angular_acceleration": ("deg/s²", DEG),
    "gyro_bias": ("deg/h", DEG_PER_HOUR),
    "gyro_scale": ("ppm", PPM),
    "gyro_misalignment": ("arcsec", ARCSEC),
    "g_sensitivity": ("deg/h/g", DEG_PER_HOUR / G0),
    "gyro_quadratic": ("ppm/(deg/s)", PPM / DEG),
    "gyro_asymmetry": ("ppm", PPM),
    "arw": ("deg/√h", DEG_PER_SQRT_HOUR),
    "vrw": ("µg/√Hz", UG_PER_SQRT_HZ),
    "length": ("mm", MM),
    "time": ("s", 1.0),
}


def to_display(kind: str, value_si: float) -> float:
    """Convert an SI value of quantity ``kind`` (a key of ``DISPLAY_UNITS``) to its display unit."""
    return value_si / DISPLAY_UNITS[kind][1]


def from_display(kind: str, value_display: float) -> float:
    """Convert a value in the display unit of quantity ``kind`` to SI."""
    return value_display * DISPLAY_UNITS[kind][1]


def display_unit(kind: str) -> str:
    """The display unit label of quantity ``kind``."""
    return DISPLAY_UNITS[kind][0]


def celsius_to_kelvin(t_c: float) -> float:
    """Temperature in °C to K."""
    return t_c + CELSIUS_ZERO


def kelvin_to_celsius(t_k: float) -> float:
    """Temperature in K to °C."""
    return t_k - CELSIUS_ZERO


# --- noise-term display units (appended for the noise analysis; IEEE 952 / IEEE 1293 conventions) ---
DEG_PER_HOUR_PER_SQRT_HOUR: float = DEG_PER_HOUR / math.sqrt(HOUR)
"""One °/h/√h (gyro rate random walk) in rad/s/√s."""
DEG_PER_HOUR2: float = DEG_PER_HOUR / HOUR
"""One °/h² (gyro rate ramp) in rad/s²."""
UG_PER_SQRT_S: float = UG
"""One µg/√s (accelerometer acceleration random walk) in m/s²/√s."""
UG_PER_S: float = UG
"""One µg/s (accelerometer ramp) in m/s³."""
MM_PER_S: float = MM
"""One mm/s (velocity quantisation) in m/s."""

DISPLAY_UNITS.update(
    {
        "angle_quantisation": ("arcsec", ARCSEC),
        "rrw": ("deg/h/√h", DEG_PER_HOUR_PER_SQRT_HOUR),
        "rate_ramp": ("deg/h²", DEG_PER_HOUR2),
        "velocity_quantisation": ("mm/s", MM_PER_S),
        "accel_random_walk": ("µg/√s", UG_PER_SQRT_S),
        "accel_ramp": ("µg/s", UG_PER_S),
    }
)


def format_hms(seconds: float) -> str:
    """A duration in s as ``h:mm:ss`` (rounded to the second; ``--:--:--`` if unknown or infinite)."""
    if not math.isfinite(seconds):
        return "--:--:--"
    s = max(0, int(round(seconds)))
    return f"{s // 3600:d}:{(s % 3600) // 60:02d}:{s % 60:02d}"


MAX_MAGNITUDE: float = 1e100
"""Largest |value| (SI) the analyses accept: sums of squares of 10⁸ such values stay far below the float64
overflow (1.8e308). A larger value is a unit or scale-factor mistake, refused with the channel and sample."""


def magnitude_problem(values: ArrayLike, sums: str) -> str | None:
    """The one rule for values too large to analyse: None if every |value| ≤ :data:`MAX_MAGNITUDE` (NaN gaps
    ignored), else the message (largest value, its sample, the limit and the fix) for the caller to raise with
    its own error type and the channel's name. ``sums`` names what would overflow (e.g. "variance")."""
    a = np.abs(np.asarray(values, dtype=np.float64).ravel())
    peak = float(np.fmax.reduce(a, initial=0.0))
    if peak <= MAX_MAGNITUDE:
        return None
    return (
        f"values up to {peak:.3g} (sample {int(np.nanargmax(a))}) are too large for the {sums} sums "
        f"(limit {MAX_MAGNITUDE:.0e}); check the channel's unit or scale factor"
    )

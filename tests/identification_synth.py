"""Synthetic accelerometer data for the identification tests (generated from the model, seeded)."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from analysis.identification import model as am
from analysis.identification.plan import PlanStep
from analysis.units import ARCSEC, MM, PPM, UG, UG_PER_G2

G = 9.80
"""Local gravity used by the synthetic bench, m/s²."""

TRUTH = np.array(
    [100 * UG, -80 * UG, 120 * UG]
    + [200 * PPM, -150 * PPM, 250 * PPM]
    + [a * ARCSEC for a in (30.0, -25.0, 20.0, 35.0, -30.0, 28.0)]
    + [20 * UG_PER_G2, -15 * UG_PER_G2, 25 * UG_PER_G2]
    + [-30 * MM, -30 * MM, -30 * MM]
)
"""Typical truth of the spec (b 100 µg, S 200 ppm, τ 30″, d 20 µg/g², r = −ρ with ρ = 3 cm), SI."""

PRIOR_SIGMA = am.sigma_from_display(
    {"bias": 1000.0, "scale": 1000.0, "misalignment": 100.0, "quadratic": 100.0, "size_effect": 30.0}
)
"""Datasheet-style prior 1σ, SI."""
P0 = np.diag(PRIOR_SIGMA**2)


def noise_sd(density_ug: float, rate: float) -> float:
    """Per-sample white-noise 1σ (m/s²) for a noise density in µg/√Hz at a sample rate in Hz."""
    return density_ug * UG * np.sqrt(rate)


def simulate(
    steps: list[PlanStep],
    x: NDArray[np.float64],
    sd: float,
    rng: np.random.Generator,
    offsets: dict[str, NDArray[np.float64]] | None = None,
) -> list[NDArray[np.float64]]:
    """Accelerometer output per step: model + white noise (1σ ``sd``) + optional per-step DC offsets (m/s²)."""
    out = []
    for st in steps:
        fo = am.predict(x, st.f_ref, st.omega) + rng.normal(0.0, sd, st.f_ref.shape)
        if offsets is not None and st.label in offsets:
            fo = fo + offsets[st.label]
        out.append(fo)
    return out

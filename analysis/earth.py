"""Earth model: WGS-84 normal gravity and Earth rate (ENU navigation frame).

Used by the simulated world (as physics) and by identification (as the reference a real bench would
compute from its site). A measured local g, when the bench file gives one, overrides the model.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

GAMMA_E: float = 9.7803253359
"""WGS-84 normal gravity at the equator, m/s²."""
K_SOMIGLIANA: float = 0.00193185265241
"""WGS-84 Somigliana constant k."""
E2: float = 0.00669437999013
"""WGS-84 first eccentricity squared."""
FREE_AIR_GRADIENT: float = 3.086e-6
"""Linear free-air gravity gradient near the surface, (m/s²)/m (documentation; the model uses the series below)."""
SEMI_MAJOR_AXIS: float = 6378137.0
"""WGS-84 semi-major axis a, m."""
FLATTENING: float = 1.0 / 298.257223563
"""WGS-84 flattening f."""
M_RATIO: float = 0.00344978650684
"""WGS-84 m = ω²a²b/GM."""
EARTH_RATE: float = 7.292115e-5
"""Earth rotation rate Ω, rad/s (WGS-84)."""


DEFAULT_LATITUDE_U: float = 4.84813681109536e-06
"""Standard uncertainty of a site latitude, rad (1″ ≈ 30 m on the ground: a map or GNSS reading), used when the
bench states none (the certificate's budget; the simulator realises it with ``realise_uncertainty_inputs``)."""


def normal_gravity(latitude: float, height: float = 0.0) -> float:
    """WGS-84 normal gravity magnitude (Somigliana) with the second-order height correction.

    γ(φ) = γ_e (1 + k sin²φ) / √(1 − e² sin²φ) on the ellipsoid, and above it (NIMA TR8350.2, eq. 4-3)

        γ(φ, h) = γ(φ) [1 − (2/a)(1 + f + m − 2 f sin²φ) h + (3/a²) h²].

    The linear term is the familiar free-air gradient ≈ 3.086e-6 h at mid latitude; the series keeps its
    latitude dependence and the h² term (a linear 3.086e-6 h is off by ~0.4 ppm of g at 1450 m).

    Parameters
    ----------
    latitude : float
        Geodetic latitude φ, rad.
    height : float
        Height above the ellipsoid h, m.

    Returns
    -------
    float
        Local gravity magnitude g, m/s² (positive).
    """
    s2 = np.sin(latitude) ** 2
    g0 = GAMMA_E * (1.0 + K_SOMIGLIANA * s2) / np.sqrt(1.0 - E2 * s2)
    a = SEMI_MAJOR_AXIS
    corr = 1.0 - 2.0 / a * (1.0 + FLATTENING + M_RATIO - 2.0 * FLATTENING * s2) * height + 3.0 * height**2 / a**2
    return float(g0 * corr)


def earth_rate_enu(latitude: float) -> NDArray[np.float64]:
    """Earth rotation vector in the local ENU frame, rad/s: [0, Ω cos φ, Ω sin φ]."""
    return np.array([0.0, EARTH_RATE * np.cos(latitude), EARTH_RATE * np.sin(latitude)])


def gravity_specific_force_enu(g: float) -> NDArray[np.float64]:
    """Specific force sensed at rest in ENU, m/s²: [0, 0, +g] (an upward reading when z is up)."""
    return np.array([0.0, 0.0, g])

"""Thermal calibration maths (docs/methods/thermal.md).

- :mod:`analysis.thermal.soak` — the soak criterion: is the unit's temperature settled at a plateau?
- :mod:`analysis.thermal.model` — parameters as polynomials in (T − T_ref), order by BIC, full covariance,
  optional dT/dt term; residual after compensation; hysteresis.
"""

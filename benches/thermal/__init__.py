"""Thermal calibration on the bench (docs/methods/thermal.md).

- :mod:`benches.thermal.simrun` — a thermal calibration run on the simulated world: plateaus, soak, the
  calibration sequence at each plateau, per-plateau identification, the temperature model.
- :mod:`benches.thermal.plateau` — per-plateau identification of both triads from held and spun windows.
"""

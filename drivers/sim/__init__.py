"""The simulated bench: one clock driving a three-axis table, an inertial unit and the Earth.

- :mod:`drivers.sim.config` — :class:`SimConfig` and its parts (truth, noise, table model), SI.
- :mod:`drivers.sim.bench_section` — parses a bench file's ``simulation:`` section into a ``SimConfig``.
- :mod:`drivers.sim.world` — :class:`SimulatedWorld` (thread-safe; used by every simulated driver).
- :mod:`drivers.sim.motion` — piecewise-analytic axis motion profiles.
- :mod:`drivers.sim.imu_model` — the unit's physics, errors, noise and output stage.
- :mod:`drivers.sim.inprocess` — ``SimTurntable`` / ``SimInertialUnit`` device-level drivers.
"""

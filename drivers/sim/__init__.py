"""The simulated bench: one clock driving a three-axis table, an inertial unit and the Earth.

- :mod:`drivers.sim.config` — :class:`SimConfig` and its parts (truth, noise, table model), SI.
- :mod:`drivers.sim.bench_section` — parses a bench file's ``simulation:`` section into a ``SimConfig``.
- :mod:`drivers.sim.world` — :class:`SimulatedWorld` (thread-safe; used by every simulated driver).
- :mod:`drivers.sim.motion` — piecewise-analytic axis motion profiles.
- :mod:`drivers.sim.imu_model` — the unit's physics, errors, noise and output stage.
- :mod:`drivers.sim.inprocess` — ``SimTurntable`` / ``SimInertialUnit`` device-level drivers.
- :mod:`drivers.sim.acl_controller`, :mod:`drivers.sim.acl_server` — the simulated ACUTROL3000 (ACL), in memory
  and on loopback TCP (pyvisa-py TCPIP SOCKET).
- :mod:`drivers.sim.modbus_controller` — the simulated Modbus table (any register map).
- :mod:`drivers.sim.serial_unit` — the unit's serial frames on loopback; :mod:`drivers.sim.loopback` wires them.
- :mod:`drivers.sim.tcp_server` — the lifecycle shared by the single-client loopback servers.
"""

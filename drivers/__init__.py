"""The seams (:mod:`drivers.protocols`: ``Turntable``, ``InertialUnit``, ``AxisLimits``), the real drivers
(Modbus / ASCII turntables, the serial unit and its frame format) and, in :mod:`drivers.sim`, the simulated
world served both in-process and over the same wire protocols. Imports ``core`` and ``analysis`` only."""

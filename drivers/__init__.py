"""The seams (:mod:`drivers.protocols`: ``Turntable``, ``InertialUnit``, ``AxisLimits``), the real drivers
(ACUTROL over VISA and Modbus turntables, the serial unit and its frame formats), :mod:`drivers.connect` (the
one place a transport is opened and a driver built on it) and, in :mod:`drivers.sim`, the simulated world
served both in-process and over the same wire protocols. Imports ``core`` and ``analysis`` only."""

"""Inertial units over a binary frame stream: frame descriptions (``frames/*.yaml``), their compiler
(:mod:`drivers.imu_unit.description`), the vectorised decoder (:mod:`drivers.imu_unit.decoder`), checksums
(:mod:`drivers.imu_unit.checksums`), conversion to SI samples (:mod:`drivers.imu_unit.samples`), counter
accounting (:mod:`drivers.imu_unit.counts`) and the serial unit driver (:mod:`drivers.imu_unit.serial_unit`)."""

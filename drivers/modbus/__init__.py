"""Modbus/PLC turntables: the register map as data (:mod:`drivers.modbus.register_map`, ``maps/*.yaml``),
register packing (:mod:`drivers.modbus.registers`) and the driver (:mod:`drivers.modbus.table`)."""

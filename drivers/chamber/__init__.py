"""Temperature chamber drivers: auxiliary devices of the bench (docs/protocols/chambers.md).

- :mod:`drivers.chamber.base` — :class:`Chamber` protocol, :class:`ChamberReading`, :class:`ChamberSettings`,
  errors; temperatures are kelvin inside, °C only on the wire.
- :mod:`drivers.chamber.stream` — the byte-stream seam (pyserial ``Serial`` or ``socket://`` URL) and the
  CR-LF line channel built on it.
- :mod:`drivers.chamber.modbus_rtu` — Modbus RTU / TCP framing (CRC-16/MODBUS, MBAP) for the Watlow drivers.
- :mod:`drivers.chamber.watlow` — Watlow F4 (16-bit scaled registers) and F4T (IEEE-754 float pairs).
- :mod:`drivers.chamber.espec` — Espec ASCII command set (P-300, SCP-220, SH-641 family).
- :mod:`drivers.chamber.simserv` — Vötsch / Weiss Technik S!MPAC simserv over TCP.
- :mod:`drivers.chamber.safety` — what every exit path does to the chamber (safe set point, warm-up, stop).
- :mod:`drivers.chamber.connect` — opens the link and builds the driver (drivers never open ports).
"""

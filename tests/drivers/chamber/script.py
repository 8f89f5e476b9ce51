"""A scripted byte stream for the chamber drivers' exact-bytes tests: every write must equal the next scripted
request, byte for byte; the scripted reply is then what ``read`` returns. Written from the thermal-chamber
spec's exchanges, never from the simulator."""

from __future__ import annotations

import struct

from tests.drivers.transcript import ByteTranscript, h

__all__ = ["FakeClock", "ScriptedStream", "h", "rtu"]


def rtu(body: str) -> bytes:
    """An RTU frame with the CRC computed by pymodbus (an independent implementation), low byte first."""
    from pymodbus.framer import FramerRTU

    data = h(body)
    return data + struct.pack(">H", FramerRTU.compute_CRC(data))


ScriptedStream = ByteTranscript
"""A ByteStream (``write``/``read``/``timeout``) that checks requests against a script: the one transcript
helper of the driver tests (tests/drivers/transcript.py)."""


class FakeClock:
    """A monotonic clock that advances on every call (so a missing reply times out at once)."""

    def __init__(self, step: float = 0.05) -> None:
        self.t = 0.0
        self.step = step
        self.slept: list[float] = []

    def __call__(self) -> float:
        self.t += self.step
        return self.t

    def sleep(self, s: float) -> None:
        self.slept.append(s)
        self.t += s

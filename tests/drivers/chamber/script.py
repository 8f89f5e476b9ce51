"""A scripted byte stream for the chamber drivers' exact-bytes tests: every write must equal the next scripted
request, byte for byte; the scripted reply is then what ``read`` returns. Written from the thermal-chamber
spec's exchanges, never from the simulator."""

from __future__ import annotations

import struct


def h(text: str) -> bytes:
    """Bytes from spaced hex, e.g. ``h("01 03 00 64")``."""
    return bytes.fromhex(text)


def rtu(body: str) -> bytes:
    """An RTU frame with the CRC computed by pymodbus (an independent implementation), low byte first."""
    from pymodbus.framer import FramerRTU

    data = h(body)
    return data + struct.pack(">H", FramerRTU.compute_CRC(data))


class ScriptedStream:
    """A ByteStream (``write``/``read``/``timeout``) that checks requests against a script."""

    def __init__(self, script: list[tuple[bytes, bytes | None]]) -> None:
        self.script = list(script)
        self.timeout = 0.01
        self._pending = bytearray()
        self.sent: list[bytes] = []

    def write(self, data: bytes) -> int:
        assert self.script, f"unexpected request {data.hex(' ')}"
        expected, reply = self.script.pop(0)
        assert data == expected, f"sent {data.hex(' ')}, the spec says {expected.hex(' ')}"
        self.sent.append(data)
        if reply is not None:
            self._pending += reply
        return len(data)

    @property
    def in_waiting(self) -> int:
        return len(self._pending)

    def read(self, size: int = 1) -> bytes:
        out = bytes(self._pending[:size])
        del self._pending[:size]
        return out

    def done(self) -> None:
        assert not self.script, f"requests never sent: {[q.hex(' ') for q, _ in self.script]}"


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

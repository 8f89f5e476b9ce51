"""One exact-bytes transcript helper for every driver test (after PyMeasure's ``expected_protocol`` in
``pymeasure/test.py``): a fake transport that asserts the exact sequence of what the driver sends and answers
each request with the scripted reply. Transcripts are written from the protocol's documentation (docs/protocols/),
never from the simulator.

One core (:class:`Transcript`: a list of ``(request, reply)`` pairs; ``reply`` ``None`` = the device answers
nothing) and three faces, one per kind of link a driver receives:

* :class:`MessageTranscript` — a :class:`drivers.transport.MessageTransport` (``write``/``read``/``query``;
  text messages: ACL, Ideal Aerosmith);
* :class:`ByteTranscript` — a pyserial-like byte stream (``write``/``read``/``in_waiting``/``timeout``;
  Modbus RTU chambers, ASCII chambers, serial units);
* :class:`ModbusTranscript` — a pymodbus-like synchronous client whose calls are encoded to their Modbus
  request PDUs (function code, address, count/values; Modbus Application Protocol V1.1b3 §6) and compared
  byte for byte; the scripted reply is the response PDU, decoded as pymodbus would.

Usage::

    with expected_protocol(lambda link: AclTurntable(link, ...), [(":Mode:Off 1", ""), ...]) as drv:
        drv.stop()

The block's end asserts that every scripted request was sent (unless the block raised).
"""

from __future__ import annotations

import struct
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from typing import Any, Generic, TypeVar

T = TypeVar("T", str, bytes)


def h(text: str) -> bytes:
    """Bytes from spaced hex, e.g. ``h("01 03 00 64")``."""
    return bytes.fromhex(text)


def _show(x: object) -> str:
    return x.hex(" ") if isinstance(x, (bytes, bytearray)) else repr(x)


class Transcript(Generic[T]):
    """The script: requests the driver must send, in order, each with the device's reply (or None)."""

    def __init__(self, pairs: Sequence[tuple[T, T | None]]) -> None:
        self.script: list[tuple[T, T | None]] = list(pairs)
        self.sent: list[T] = []

    def exchange(self, request: T) -> T | None:
        """Check ``request`` against the next scripted one; return the scripted reply."""
        assert self.script, f"unexpected request {_show(request)} (the transcript is finished)"
        expected, reply = self.script.pop(0)
        assert request == expected, f"sent {_show(request)}, the protocol says {_show(expected)}"
        self.sent.append(request)
        return reply

    def done(self) -> None:
        """Assert every scripted request was sent."""
        assert not self.script, f"requests never sent: {[_show(q) for q, _ in self.script]}"


class MessageTranscript(Transcript[str]):
    """A text :class:`~drivers.transport.MessageTransport`; a read with no reply pending is a dead link."""

    def __init__(self, pairs: Sequence[tuple[str, str | None]], timeout: float = 1.0) -> None:
        super().__init__(pairs)
        self.timeout = timeout
        self._pending: list[str] = []

    def write(self, message: str) -> None:
        reply = self.exchange(message)
        if reply is not None:
            self._pending.append(reply)

    def read(self) -> str:
        from drivers.protocols import LinkError

        if not self._pending:
            raise LinkError(f"transcript: no reply within {self.timeout:g} s")
        return self._pending.pop(0)

    def query(self, message: str) -> str:
        self.write(message)
        return self.read()


class ByteTranscript(Transcript[bytes]):
    """A pyserial-like byte stream: each ``write`` must equal the next request; replies queue for ``read``.

    ``initial`` is what the device sends unasked before the first request (a free-running unit's frames).
    """

    def __init__(
        self, pairs: Sequence[tuple[bytes, bytes | None]], timeout: float = 0.01, initial: bytes = b""
    ) -> None:
        super().__init__(pairs)
        self.timeout = timeout
        self._pending = bytearray(initial)

    def write(self, data: bytes) -> int:
        reply = self.exchange(bytes(data))
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

    def read_until(self, expected: bytes = b"\n", size: int | None = None) -> bytes:
        i = self._pending.find(expected)
        n = len(self._pending) if i < 0 else i + len(expected)
        return self.read(n if size is None else min(n, size))

    def reset_input_buffer(self) -> None:
        self._pending.clear()

    def flush(self) -> None:
        pass


# ---- Modbus: requests as PDUs (Modbus Application Protocol V1.1b3 §6) --------------------------------------
def read_holding(address: int, words: Sequence[int]) -> tuple[bytes, bytes]:
    """FC 03 request for ``len(words)`` holding registers at ``address`` and its response."""
    return struct.pack(">BHH", 3, address, len(words)), struct.pack(f">BB{len(words)}H", 3, 2 * len(words), *words)


def read_input(address: int, words: Sequence[int]) -> tuple[bytes, bytes]:
    """FC 04 request for ``len(words)`` input registers at ``address`` and its response."""
    return struct.pack(">BHH", 4, address, len(words)), struct.pack(f">BB{len(words)}H", 4, 2 * len(words), *words)


def write_registers(address: int, words: Sequence[int]) -> tuple[bytes, bytes]:
    """FC 16 (write multiple registers) request and its normal response."""
    n = len(words)
    return struct.pack(f">BHHB{n}H", 16, address, n, 2 * n, *words), struct.pack(">BHH", 16, address, n)


def write_coil(address: int, on: bool) -> tuple[bytes, bytes]:
    """FC 05 (write single coil) request and its echo response."""
    pdu = struct.pack(">BHH", 5, address, 0xFF00 if on else 0)
    return pdu, pdu


def exception(function: int, code: int) -> bytes:
    """An exception response PDU (function | 0x80, exception code)."""
    return bytes([function | 0x80, code])


class _Response:
    """A decoded response PDU, shaped as pymodbus' (``registers``, ``bits``, ``isError()``, ``exception_code``)."""

    def __init__(self, pdu: bytes) -> None:
        self.function_code = pdu[0]
        self.exception_code = pdu[1] if pdu[0] & 0x80 else None
        self.registers: list[int] = []
        self.bits: list[bool] = []
        if self.exception_code is None and pdu[0] in (3, 4):
            n = pdu[1] // 2
            self.registers = list(struct.unpack(f">{n}H", pdu[2 : 2 + 2 * n]))
        if self.exception_code is None and pdu[0] in (1, 2):
            self.bits = [bool(pdu[2 + i // 8] >> (i % 8) & 1) for i in range(8 * pdu[1])]

    def isError(self) -> bool:  # noqa: N802 - pymodbus API
        return self.exception_code is not None


class ModbusTranscript(Transcript[bytes]):
    """A pymodbus-like synchronous client: every call is encoded to its request PDU and checked byte for byte;
    a scripted reply ``None`` is no response (pymodbus returns None / the driver sees a dead link)."""

    def __init__(self, pairs: Sequence[tuple[bytes, bytes | None]], device_id: int = 1) -> None:
        super().__init__(pairs)
        self.device_id = device_id

    def _call(self, pdu: bytes, device_id: int) -> _Response | None:
        assert device_id == self.device_id, f"device id {device_id}, the bench says {self.device_id}"
        reply = self.exchange(pdu)
        return None if reply is None else _Response(reply)

    def read_holding_registers(self, address: int, count: int = 1, device_id: int = 1) -> _Response | None:
        return self._call(struct.pack(">BHH", 3, address, count), device_id)

    def read_input_registers(self, address: int, count: int = 1, device_id: int = 1) -> _Response | None:
        return self._call(struct.pack(">BHH", 4, address, count), device_id)

    def write_registers(self, address: int, values: Sequence[int], device_id: int = 1) -> _Response | None:
        v = [int(x) for x in values]
        return self._call(struct.pack(f">BHHB{len(v)}H", 16, address, len(v), 2 * len(v), *v), device_id)

    def write_register(self, address: int, value: int, device_id: int = 1) -> _Response | None:
        return self._call(struct.pack(">BHH", 6, address, int(value)), device_id)

    def write_coil(self, address: int, value: bool, device_id: int = 1) -> _Response | None:
        return self._call(struct.pack(">BHH", 5, address, 0xFF00 if value else 0), device_id)


@contextmanager
def expected_protocol(
    make_driver: Callable[[Any], Any], pairs: Sequence[tuple[Any, Any]], link: type[Transcript] | None = None, **kw: Any
) -> Iterator[Any]:
    """Build a driver on a transcript of ``pairs`` and check, at the end of the block, that all were sent.

    ``link`` chooses the face (default: :class:`MessageTranscript` for ``str`` requests, :class:`ByteTranscript`
    for ``bytes``); ``kw`` go to the face. :func:`transcript_of` gives a test the transcript under the driver.
    """
    if link is None:
        link = MessageTranscript if pairs and isinstance(pairs[0][0], str) else ByteTranscript
    t = link(pairs, **kw)
    driver = make_driver(t)
    _LINKS[id(driver)] = t
    try:
        yield driver
    finally:
        _LINKS.pop(id(driver), None)
    t.done()


_LINKS: dict[int, Transcript] = {}


def transcript_of(driver: Any) -> Transcript:
    """The transcript under a driver built by :func:`expected_protocol` (inside its block)."""
    return _LINKS[id(driver)]

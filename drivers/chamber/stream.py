"""The byte-stream seam of the chamber drivers and the CR-LF line channel on top of it.

A :class:`ByteStream` is what ``serial.Serial`` and ``serial.serial_for_url("socket://host:port")`` already are:
``write(bytes)``, ``read(n)`` returning at most ``n`` bytes (fewer on its own short time-out), and a
``timeout`` attribute. The chamber drivers receive one already open (:mod:`drivers.chamber.connect` opens it)
and bound every wait by their own deadline, so a silent chamber is a :class:`ChamberLinkError`, never a hang.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Protocol, runtime_checkable

from drivers.chamber.base import ChamberLinkError


@runtime_checkable
class ByteStream(Protocol):
    """An open byte link (a pyserial ``Serial``-like object)."""

    timeout: float | None

    def write(self, data: bytes) -> int | None:
        """Send bytes."""
        ...

    def read(self, size: int = 1) -> bytes:
        """Return up to ``size`` bytes (fewer, possibly none, when the link's own time-out expires)."""
        ...


class StreamReader:
    """Deadline-bounded reads from a :class:`ByteStream` (shared by the line and Modbus framings).

    Parameters
    ----------
    stream : ByteStream
    name : str
        Names the chamber in error messages.
    timeout : float
        Longest wait for one complete reply, s.
    clock : callable
        Monotonic clock, s (tests may pass a fake).
    """

    def __init__(self, stream: ByteStream, name: str, timeout: float, clock: Callable[[], float] = time.monotonic):
        self.stream = stream
        self.name = name
        self.timeout = float(timeout)
        self._clock = clock
        self._buf = bytearray()

    def write(self, data: bytes) -> None:
        """Send ``data`` (a failing link is a ChamberLinkError)."""
        try:
            self.stream.write(bytes(data))
        except (OSError, ValueError) as exc:  # serial.SerialException is an OSError
            raise ChamberLinkError(f"{self.name}: link failed while sending ({exc})") from exc

    def discard_input(self) -> None:
        """Drop bytes left over from an earlier, abandoned reply."""
        self._buf.clear()
        reset = getattr(self.stream, "reset_input_buffer", None)
        if reset is not None:
            try:
                reset()
            except (OSError, ValueError):
                pass

    def _fill(self, deadline: float, what: str) -> None:
        if self._clock() > deadline:
            raise ChamberLinkError(
                f"{self.name}: no complete reply within {self.timeout:.3g} s to {what}; check power, cable, "
                "address and the line settings in the bench file"
            )
        try:
            chunk = self.stream.read(1)  # waits at most the stream's own short time-out
            waiting = int(getattr(self.stream, "in_waiting", 0) or 0) if chunk else 0
            if waiting > 0:
                chunk += self.stream.read(waiting)
        except (OSError, ValueError) as exc:
            raise ChamberLinkError(f"{self.name}: link failed while reading the reply to {what} ({exc})") from exc
        if chunk:
            self._buf += chunk

    def read_exact(self, n: int, deadline: float, what: str) -> bytes:
        """Exactly ``n`` bytes before ``deadline`` (clock time)."""
        while len(self._buf) < n:
            self._fill(deadline, what)
        out = bytes(self._buf[:n])
        del self._buf[:n]
        return out

    def read_until(self, terminator: bytes, deadline: float, what: str, limit: int = 4096) -> bytes:
        """Bytes up to and including ``terminator`` before ``deadline``."""
        while True:
            i = self._buf.find(terminator)
            if i >= 0:
                out = bytes(self._buf[: i + len(terminator)])
                del self._buf[: i + len(terminator)]
                return out
            if len(self._buf) > limit:
                raise ChamberLinkError(f"{self.name}: reply to {what} exceeds {limit} bytes without a terminator")
            self._fill(deadline, what)

    def deadline(self) -> float:
        """Clock time by which the reply must be complete."""
        return self._clock() + self.timeout


class LineChannel:
    """Text lines over a :class:`ByteStream`: ASCII, ``terminator`` (CR LF) after every line in both directions.

    Implements the :class:`drivers.transport.MessageTransport` methods (``write``, ``read``, ``query``), so the
    Espec driver talks through this or through a VISA resource alike.
    """

    def __init__(
        self,
        stream: ByteStream,
        name: str = "chamber",
        timeout: float = 3.0,
        terminator: bytes = b"\r\n",
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.reader = StreamReader(stream, name, timeout, clock)
        self.terminator = terminator
        self.name = name

    @property
    def timeout(self) -> float:
        """Reply time-out, s."""
        return self.reader.timeout

    @timeout.setter
    def timeout(self, seconds: float) -> None:
        self.reader.timeout = float(seconds)

    def write(self, message: str) -> None:
        """Send one line (ASCII; the terminator is added here)."""
        try:
            data = message.encode("ascii")
        except UnicodeEncodeError as exc:
            raise ValueError(f"{self.name}: command {message!r} is not ASCII") from exc
        self.reader.write(data + self.terminator)

    def read(self) -> str:
        """One reply line without its terminator (a lone CR or LF before it is stripped as well)."""
        raw = self.reader.read_until(self.terminator, self.reader.deadline(), "a command")
        try:
            return raw[: -len(self.terminator)].decode("ascii").strip("\r\n")
        except UnicodeDecodeError as exc:
            raise ChamberLinkError(f"{self.name}: reply {raw!r} is not ASCII text") from exc

    def query(self, message: str) -> str:
        """Send one line, return the reply line."""
        self.write(message)
        return self.read()

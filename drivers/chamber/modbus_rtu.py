"""Modbus framing for chamber controllers: RTU (CRC-16/MODBUS) and TCP (MBAP) over a byte stream.

Only what the Watlow drivers need: read holding / input registers (03 / 04), write one register (06), write
several (16). Written here rather than through pymodbus' client so that the bytes on the wire, the pacing
the Watlow documentation recommends after a send (30 ms) and the time-outs are the driver's, and exact-bytes
tests can script them (docs/protocols/chambers.md).

CRC-16/MODBUS: reflected polynomial 0xA001, initial value 0xFFFF, sent low byte first; ``crc16(b"123456789")
== 0x4B37``.
"""

from __future__ import annotations

import struct
import time
from collections.abc import Callable
from typing import Literal

from drivers.chamber.base import ChamberError, ChamberLinkError
from drivers.chamber.stream import ByteStream, StreamReader

Framing = Literal["rtu", "tcp"]

EXCEPTION_NAMES = {
    1: "illegal function",
    2: "illegal data address",
    3: "illegal data value",
    4: "slave device failure",
    5: "acknowledge",
    6: "slave device busy",
    7: "negative acknowledge",
    8: "memory parity error",
    10: "gateway path unavailable",
    11: "gateway target failed to respond",
}


def _crc_table() -> tuple[int, ...]:
    table = []
    for byte in range(256):
        crc = byte
        for _ in range(8):
            crc = (crc >> 1) ^ 0xA001 if crc & 1 else crc >> 1
        table.append(crc)
    return tuple(table)


_CRC_TABLE = _crc_table()


def crc16(data: bytes) -> int:
    """CRC-16/MODBUS of ``data`` (the integer; on the wire low byte first)."""
    crc = 0xFFFF
    for b in data:
        crc = (crc >> 8) ^ _CRC_TABLE[(crc ^ b) & 0xFF]
    return crc


def with_crc(frame: bytes) -> bytes:
    """``frame`` followed by its CRC, low byte first."""
    return frame + struct.pack("<H", crc16(frame))


class ModbusMaster:
    """A Modbus master on an open byte stream (one request, one reply; no pipelining).

    Parameters
    ----------
    stream : ByteStream
        Open serial port (RTU) or TCP stream (TCP framing; RTU framing over a serial-to-Ethernet forwarder).
    framing : {"rtu", "tcp"}
    address : int
        Modbus address (RTU) / unit id (TCP), 1–247.
    timeout : float
        Longest wait for a reply, s.
    send_delay : float
        Pause after each request before reading, s (Watlow recommends 30 ms on RTU).
    name : str
        For messages.
    clock, sleep : callable
        Time functions (tests pass fakes).
    """

    def __init__(
        self,
        stream: ByteStream,
        framing: Framing = "rtu",
        address: int = 1,
        *,
        timeout: float = 3.0,
        send_delay: float = 0.0,
        name: str = "chamber",
        clock: Callable[[], float] = time.monotonic,
        sleep: Callable[[float], None] = time.sleep,
    ) -> None:
        if framing not in ("rtu", "tcp"):
            raise ValueError(f"Modbus framing must be 'rtu' or 'tcp', got {framing!r}")
        if not 1 <= int(address) <= 247:
            raise ValueError(f"Modbus address must be 1..247, got {address!r}")
        self.io = StreamReader(stream, name, timeout, clock)
        self.framing = framing
        self.address = int(address)
        self.send_delay = float(send_delay)
        self.name = name
        self._sleep = sleep
        self._tid = 0

    # ---- framing -------------------------------------------------------------------------------------
    def _frame(self, pdu: bytes) -> bytes:
        if self.framing == "rtu":
            return with_crc(bytes([self.address]) + pdu)
        self._tid = self._tid % 0xFFFF + 1
        return struct.pack(">HHHB", self._tid, 0, len(pdu) + 1, self.address) + pdu

    def _reply_pdu(self, function: int, what: str) -> bytes:
        deadline = self.io.deadline()
        if self.framing == "tcp":
            head = self.io.read_exact(7, deadline, what)
            tid, proto, length, unit = struct.unpack(">HHHB", head)
            if proto != 0 or not 2 <= length <= 254:
                raise ChamberLinkError(f"{self.name}: malformed MBAP header {head.hex(' ')} in the reply to {what}")
            pdu = self.io.read_exact(length - 1, deadline, what)
            if tid != self._tid or unit != self.address:
                raise ChamberLinkError(
                    f"{self.name}: reply to {what} has transaction {tid} / unit {unit}, expected {self._tid} / "
                    f"{self.address}"
                )
            return pdu
        head = self.io.read_exact(2, deadline, what)
        if head[0] != self.address:
            raise ChamberLinkError(f"{self.name}: reply to {what} from address {head[0]}, expected {self.address}")
        fc = head[1]
        if fc & 0x80:
            rest = self.io.read_exact(3, deadline, what)
        elif fc in (3, 4):
            count = self.io.read_exact(1, deadline, what)
            rest = count + self.io.read_exact(count[0] + 2, deadline, what)
        elif fc in (6, 16):
            rest = self.io.read_exact(6, deadline, what)
        else:
            raise ChamberLinkError(f"{self.name}: unexpected function code {fc} in the reply to {what}")
        frame = head + rest
        if crc16(frame[:-2]) != struct.unpack("<H", frame[-2:])[0]:
            raise ChamberLinkError(f"{self.name}: CRC error in the reply to {what} ({frame.hex(' ')})")
        return frame[1:-2]

    def _transact(self, pdu: bytes, what: str) -> bytes:
        self.io.discard_input()
        self.io.write(self._frame(pdu))
        if self.send_delay > 0:
            self._sleep(self.send_delay)
        reply = self._reply_pdu(pdu[0], what)
        if reply[0] == (pdu[0] | 0x80) and len(reply) == 2:
            code = reply[1]
            raise ChamberError(
                f"{self.name}: {what} refused with Modbus exception {code} "
                f"({EXCEPTION_NAMES.get(code, 'unknown code')})"
            )
        if reply[0] != pdu[0]:
            raise ChamberLinkError(f"{self.name}: reply to {what} has function {reply[0]}, expected {pdu[0]}")
        return reply

    # ---- functions -----------------------------------------------------------------------------------
    def read_registers(self, address: int, count: int = 1, function: int = 3) -> list[int]:
        """Read ``count`` 16-bit registers (unsigned) from ``address`` with function 03 or 04."""
        what = f"a read of register {address} (function {function:02d})"
        reply = self._transact(struct.pack(">BHH", function, address, count), what)
        if len(reply) != 2 + 2 * count or reply[1] != 2 * count:
            raise ChamberLinkError(
                f"{self.name}: reply to {what} has {len(reply) - 2} data bytes, expected {2 * count}"
            )
        return list(struct.unpack(f">{count}H", reply[2:]))

    def write_register(self, address: int, value: int) -> None:
        """Write one 16-bit register (function 06; ``value`` 0..65535); the echo is checked."""
        pdu = struct.pack(">BHH", 6, address, value & 0xFFFF)
        what = f"a write of register {address}"
        reply = self._transact(pdu, what)
        if reply != pdu:
            raise ChamberLinkError(f"{self.name}: {what} echoed {reply.hex(' ')}, expected {pdu.hex(' ')}")

    def write_registers(self, address: int, values: list[int]) -> None:
        """Write consecutive 16-bit registers (function 16); the reply's address and count are checked."""
        n = len(values)
        pdu = struct.pack(f">BHHB{n}H", 16, address, n, 2 * n, *[v & 0xFFFF for v in values])
        what = f"a write of registers {address}..{address + n - 1}"
        reply = self._transact(pdu, what)
        if reply != pdu[:5]:
            raise ChamberLinkError(f"{self.name}: {what} answered {reply.hex(' ')}, expected {pdu[:5].hex(' ')}")

"""The simulated chamber on loopback TCP, in each dialect (docs/protocols/chambers.md).

Each server answers from ONE :class:`~drivers.sim.world.SimulatedWorld`'s chamber (``world.chamber_*``):

* :class:`WatlowServer` — Watlow F4 (scaled 16-bit registers) or F4T (float pairs), Modbus RTU framing over the
  TCP stream (as through a serial-to-Ethernet forwarder) or Modbus TCP (MBAP) framing;
* :class:`EspecServer` — Espec ASCII lines (CR LF; accepts an RS-485 address prefix and both set-point forms);
* :class:`SimservServer` — simserv (fields joined by B6, requests end CR; tolerates a leading separator).

They accept every variant the spec leaves open, so a driver set either way can talk to them, and can inject the
faults a real chamber shows: silence (``mute``), refusals, an alarm (``world.chamber.alarm``).
"""

from __future__ import annotations

import logging
import re
import select
import socket
import struct
from typing import TYPE_CHECKING, Literal

from analysis.units import celsius_to_kelvin, kelvin_to_celsius
from drivers.chamber.modbus_rtu import crc16, with_crc
from drivers.sim.tcp_server import SingleClientServer

if TYPE_CHECKING:
    from drivers.sim.world import SimulatedWorld

log = logging.getLogger(__name__)


class _ChamberServer(SingleClientServer):
    """A loopback server that hands the client's bytes to :meth:`_consume` and sends what it returns."""

    world: SimulatedWorld
    mute: bool = False
    """True: read requests but never answer (a dead chamber)."""

    def _start(self, world: SimulatedWorld, port: int, thread: str) -> None:
        self.world = world
        self.mute = False
        self._listen(port, thread)
        self._thread.start()

    def _consume(self, buf: bytearray) -> bytes:
        raise NotImplementedError

    def _handle(self, conn: socket.socket) -> None:
        buf = bytearray()
        while not self._stop.is_set():
            r, _, _ = select.select([conn], [], [], 0.05)
            if not r:
                continue
            chunk = conn.recv(4096)
            if not chunk:
                return
            buf += chunk
            out = self._consume(buf)
            if out and not self.mute:
                conn.sendall(out)
            if len(buf) > 8192:
                buf.clear()

    # ---- the chamber, in °C ---------------------------------------------------------------------------
    def _reading_c(self) -> tuple[float, float, bool, bool]:
        sp, air, running, alarm = self.world.chamber_reading()
        return kelvin_to_celsius(sp), kelvin_to_celsius(air), running, alarm

    def _set_c(self, celsius: float) -> bool:
        return self.world.chamber_setpoint(celsius_to_kelvin(celsius))

    def _limits_c(self) -> tuple[float, float]:
        cfg = self.world.chamber.cfg  # type: ignore[union-attr]
        return kelvin_to_celsius(cfg.setpoint_min), kelvin_to_celsius(cfg.setpoint_max)


class WatlowServer(_ChamberServer):
    """A simulated Watlow F4 or F4T.

    Parameters
    ----------
    world : SimulatedWorld
    model : {"f4", "f4t"}
    framing : {"rtu", "tcp"}
    address : int
        Modbus address answered (RTU) / unit id (TCP).
    decimals : int
        F4 register 606.
    word_order : {"low_first", "high_first"}
        F4T float word order.
    run_event : int or None
        F4: the event wired to "chamber on" (None: the chamber always runs).
    port : int
    """

    name = "simulated Watlow"

    def __init__(
        self,
        world: SimulatedWorld,
        model: Literal["f4", "f4t"] = "f4",
        framing: Literal["rtu", "tcp"] = "rtu",
        *,
        address: int = 1,
        decimals: int = 1,
        word_order: Literal["low_first", "high_first"] = "low_first",
        run_event: int | None = None,
        port: int = 0,
    ) -> None:
        self.model, self.framing, self.address = model, framing, int(address)
        self.decimals, self.word_order, self.run_event = int(decimals), word_order, run_event
        self.events = [0] * 8
        self.requests = 0
        if run_event is None:
            world.chamber_run(True)
        self._start(world, port, f"sim-watlow-{model}")

    # ---- framing ----------------------------------------------------------------------------------------
    def _consume(self, buf: bytearray) -> bytes:
        out = b""
        while True:
            if self.framing == "tcp":
                if len(buf) < 7:
                    return out
                tid, _, length, unit = struct.unpack(">HHHB", bytes(buf[:7]))
                if len(buf) < 6 + length:
                    return out
                pdu = bytes(buf[7 : 6 + length])
                del buf[: 6 + length]
                reply = self._pdu(pdu)
                out += struct.pack(">HHHB", tid, 0, len(reply) + 1, unit) + reply
                continue
            if len(buf) < 8:
                return out
            fc = buf[1]
            n = 8 if fc in (3, 4, 6) else (9 + buf[6] if fc == 16 and len(buf) >= 7 else 0)
            if n == 0 or len(buf) < n:
                if n == 0:
                    buf.clear()  # unknown function: the frame length is unknown, resynchronise
                return out
            frame = bytes(buf[:n])
            del buf[:n]
            if crc16(frame[:-2]) != struct.unpack("<H", frame[-2:])[0] or frame[0] != self.address:
                continue  # a real slave ignores a corrupt frame or another address
            out += with_crc(bytes([self.address]) + self._pdu(frame[1:-2]))

    def _pdu(self, pdu: bytes) -> bytes:
        self.requests += 1
        fc = pdu[0]
        try:
            if fc in (3, 4):
                addr, count = struct.unpack(">HH", pdu[1:5])
                words = [self._read(addr + i) for i in range(count)]
                return bytes([fc, 2 * count]) + struct.pack(f">{count}H", *words)
            if fc == 6:
                addr, value = struct.unpack(">HH", pdu[1:5])
                self._write(addr, [value])
                return pdu
            if fc == 16:
                addr, count = struct.unpack(">HH", pdu[1:5])
                values = list(struct.unpack(f">{count}H", pdu[6 : 6 + 2 * count]))
                self._write(addr, values)
                return pdu[:5]
            return bytes([fc | 0x80, 1])
        except _Exception as exc:
            return bytes([fc | 0x80, exc.code])

    # ---- F4 / F4T registers ---------------------------------------------------------------------------
    def _scaled(self, celsius: float) -> int:
        return round(celsius * 10**self.decimals) & 0xFFFF

    def _float_words(self, celsius: float) -> tuple[int, int]:
        hi, lo = struct.unpack(">HH", struct.pack(">f", celsius))
        return (lo, hi) if self.word_order == "low_first" else (hi, lo)

    def _read(self, addr: int) -> int:
        sp, air, running, alarm = self._reading_c()
        lo, hi = self._limits_c()
        if self.model == "f4":
            fixed = {
                0: 5270, 100: self._scaled(air), 101: int(alarm), 200: 0, 300: self._scaled(sp),
                602: self._scaled(lo), 603: self._scaled(hi), 606: self.decimals, 608: 0, 901: 1,
            }  # fmt: skip
            if addr in fixed:
                return fixed[addr]
            if 2000 <= addr <= 2070 and (addr - 2000) % 10 == 0:
                return self.events[(addr - 2000) // 10]
            raise _Exception(2)
        floats = {2782: sp, 2810: sp, 2820: air, 2774: lo, 2776: hi}
        for base, value in floats.items():
            if addr in (base, base + 1):
                return self._float_words(value)[addr - base]
        if addr == 16568:
            return 0
        if addr == 90:
            return 32 if alarm else 138
        raise _Exception(2)

    def _write(self, addr: int, values: list[int]) -> None:
        if self.model == "f4":
            if len(values) != 1:
                raise _Exception(1)
            v = values[0]
            if addr == 300:
                celsius = (v - 0x10000 if v & 0x8000 else v) * 10.0 ** (-self.decimals)
                if not self._set_c(celsius):
                    raise _Exception(3)
            elif addr in (1217, 1210, 1209, 25):
                pass  # end / hold / resume profile, save: no profile runs in the simulated chamber
            elif 2000 <= addr <= 2070 and (addr - 2000) % 10 == 0:
                n = (addr - 2000) // 10
                self.events[n] = int(bool(v))
                if self.run_event == n + 1:
                    self.world.chamber_run(bool(v))
            else:
                raise _Exception(2)
            return
        if addr == 2782 and len(values) == 2:
            w = values if self.word_order == "high_first" else values[::-1]
            celsius = struct.unpack(">f", struct.pack(">HH", *w))[0]
            if not self._set_c(celsius):
                raise _Exception(3)
        elif addr in (16566, 16564, 16558, 16560, 16562) and len(values) == 1:
            pass
        else:
            raise _Exception(2)


class _Exception(Exception):
    def __init__(self, code: int) -> None:
        super().__init__(code)
        self.code = code


_SETPOINT = re.compile(r"^TEMP\s*,\s*S\s*(-?\d+(?:\.\d*)?)\s*(?:H\s*-?\d+(?:\.\d*)?\s*)?(?:L\s*-?\d+(?:\.\d*)?\s*)?$")


class EspecServer(_ChamberServer):
    """A simulated Espec controller (temperature only).

    Parameters
    ----------
    world : SimulatedWorld
    mon_humidity : {"empty", "absent", "value"}
        How ``MON?`` shows the humidity field of a temperature-only chamber (the spec's open point).
    port : int
    """

    name = "simulated Espec"

    def __init__(
        self, world: SimulatedWorld, mon_humidity: Literal["empty", "absent", "value"] = "empty", port: int = 0
    ) -> None:
        self.mon_humidity = mon_humidity
        self.mode = "STANDBY"
        world.chamber_run(False)
        self._start(world, port, "sim-espec")

    def _consume(self, buf: bytearray) -> bytes:
        out = b""
        while b"\n" in buf:
            i = buf.index(b"\n")
            line = bytes(buf[:i]).rstrip(b"\r").decode("ascii", "replace").strip()
            del buf[: i + 1]
            if line:
                out += self.answer(line).encode("ascii") + b"\r\n"
        return out

    def answer(self, line: str) -> str:
        """The reply line to one command line (an RS-485 address prefix ``n,`` is accepted and dropped)."""
        m = re.match(r"^(\d{1,2}),(.*)$", line)
        cmd = m.group(2).strip() if m else line
        up = cmd.upper()
        sp, air, running, alarm = self._reading_c()
        lo, hi = self._limits_c()
        if up == "TEMP?":
            return f"{air:.1f},{sp:.1f},{hi:.1f},{lo:.1f}"
        if up == "MON?":
            hum = {"empty": ",", "absent": "", "value": ",0"}[self.mon_humidity]
            return f"{air:.1f}{hum},{self.mode},{int(alarm)}"
        if up in ("MODE?", "MODE?,DETAIL"):
            return self.mode
        if up == "TYPE?":
            return f"T,S2,{hi:.1f}"
        if up == "ROM?":
            return "P3 SIMULATED"
        if up == "ALARM?":
            return "1,1" if alarm else "0"
        s = _SETPOINT.match(up)
        if s:
            if not self._set_c(float(s.group(1))):
                return "NA:DATA OUT OF RANGE"
            return "OK:" + cmd
        compact = "".join(up.split())
        if compact in ("MODE,CONSTANT", "MODE,STANDBY", "MODE,OFF", "POWER,ON", "POWER,OFF"):
            if compact == "MODE,CONSTANT":
                if self.mode == "OFF":
                    return "NA:CONT NOT READY-1"
                self.mode = "CONSTANT"
            elif compact == "POWER,ON":
                self.mode = "STANDBY" if self.mode == "OFF" else self.mode
            else:
                self.mode = "STANDBY" if compact == "MODE,STANDBY" else "OFF"
            self.world.chamber_run(self.mode == "CONSTANT")
            return "OK:" + cmd
        return "NA:CMD ERR"


class SimservServer(_ChamberServer):
    """A simulated Vötsch / Weiss chamber on simserv."""

    name = "simulated simserv"

    def __init__(self, world: SimulatedWorld, port: int = 0) -> None:
        world.chamber_run(False)
        self._start(world, port, "sim-simserv")

    def _consume(self, buf: bytearray) -> bytes:
        out = b""
        while b"\r" in buf:
            i = buf.index(b"\r")
            raw = bytes(buf[:i]).lstrip(b"\n").lstrip(b"\xb6")
            del buf[: i + 1]
            if buf[:1] == b"\n":
                del buf[:1]
            out += self.answer(raw).encode("latin-1") + b"\r\n"
        return out

    def answer(self, raw: bytes) -> str:
        """The reply (without CR LF) to one request's bytes (separator and CR removed)."""
        fields = raw.decode("latin-1").split("\u00b6")
        if not fields or not fields[0].strip():
            return "-1"
        if len(fields) < 2:
            return "-2"
        try:
            cmd = int(fields[0])
        except ValueError:
            return "-5"
        args = fields[2:]
        sp, air, running, alarm = self._reading_c()
        if cmd == 11001:
            if len(args) != 2:
                return "-6"
            try:
                ok = self._set_c(float(args[1]))
            except ValueError:
                return "-6"
            return "1" if ok else "-9"
        if cmd in (11002, 11004):
            return f"1\u00b6{sp if cmd == 11002 else air:.1f}" if len(args) == 1 else "-6"
        if cmd == 14001:
            if len(args) != 2 or args[1] not in ("0", "1"):
                return "-6"
            self.world.chamber_run(args[1] == "1")
            return "1"
        if cmd == 14003:
            return f"1\u00b6{int(running)}"
        if cmd == 10012:
            return f"1\u00b6{(3 if running else 1) + (8 if alarm else 0)}"
        if cmd == 99997:
            return "1\u00b6SIMULATED SIMPAC"
        return "-5"


__all__ = ["EspecServer", "SimservServer", "WatlowServer"]

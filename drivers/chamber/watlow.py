"""Watlow F4 (16-bit scaled registers) and F4T (IEEE-754 float pairs) chamber controllers over Modbus.

Register facts and their sources are in docs/protocols/chambers.md. Both drivers receive an open
:class:`~drivers.chamber.modbus_rtu.ModbusMaster` (RTU or TCP framing on an open byte stream).

F4 values are signed 16-bit two's complement with implied decimals: value = raw × 10^−dp, dp = register 606
(0–3), read once at connection unless the bench file states it. A write is rounded to the nearest count
(not truncated) and read back. Temperatures are K inside, °C on the wire (register 901 must say °C).
"""

from __future__ import annotations

import math
import struct
from dataclasses import dataclass
from typing import Literal

from drivers.chamber.base import (
    ChamberError,
    ChamberLinkError,
    ChamberReading,
    ChamberSettings,
    from_wire_celsius,
    to_wire_celsius,
)
from drivers.chamber.modbus_rtu import ModbusMaster

PROFILE_STATES = {0: "constant", 1: "constant", 2: "profile running", 3: "profile paused"}


@dataclass(frozen=True)
class WatlowF4Settings:
    """Open points of the F4 as bench settings (docs/protocols/chambers.md, defaults documented there).

    Attributes
    ----------
    loop : {1, 2}
        Control loop of the air temperature (PV 100 / 104, SP 300 / 319).
    decimals : int or None
        Implied decimals 0–3; None reads register 606 at connection (default).
    pv_function : {3, 4}
        Function code of the PV read: 03 (holding, as the public clients) or 04 (input, one client).
    run_event : int or None
        Digital event 1–8 the site wired to "chamber on" (register 2000 + 10(n−1)); None: not wired.
    check_units : bool
        Read register 901 at connection and refuse a controller set to °F (default True).
    """

    loop: int = 1
    decimals: int | None = None
    pv_function: int = 3
    run_event: int | None = None
    check_units: bool = True

    def __post_init__(self) -> None:
        if self.loop not in (1, 2):
            raise ValueError(f"Watlow F4 loop must be 1 or 2, got {self.loop!r}")
        if self.decimals is not None and self.decimals not in (0, 1, 2, 3):
            raise ValueError(f"Watlow F4 decimals must be 0..3, got {self.decimals!r}")
        if self.pv_function not in (3, 4):
            raise ValueError(f"Watlow F4 pv_function must be 3 or 4, got {self.pv_function!r}")
        if self.run_event is not None and not 1 <= self.run_event <= 8:
            raise ValueError(f"Watlow F4 run_event must be 1..8, got {self.run_event!r}")


class WatlowF4:
    """Watlow F4 chamber controller (:class:`drivers.chamber.base.Chamber`).

    Parameters
    ----------
    master : ModbusMaster
        Open Modbus master (RTU or TCP framing).
    settings : ChamberSettings
    f4 : WatlowF4Settings
    name : str
    """

    PV = (100, 104)
    SP = (300, 319)
    INPUT_ERROR = 101
    PROFILE_STATE = 200
    DECIMALS = 606
    UNITS = 901
    END_PROFILE = 1217

    def __init__(
        self,
        master: ModbusMaster,
        settings: ChamberSettings | None = None,
        f4: WatlowF4Settings | None = None,
        name: str = "Watlow F4",
    ) -> None:
        self.m = master
        self.settings = settings or ChamberSettings()
        self.f4 = f4 or WatlowF4Settings()
        self.name = name
        self.decimals = self.f4.decimals
        self._closed = False

    def connect(self) -> None:
        """Read what the driver needs to know before anything is written: decimals (606), units (901)."""
        if self.decimals is None:
            dp = self.m.read_registers(self.DECIMALS)[0]
            if dp not in (0, 1, 2, 3):
                raise ChamberError(f"{self.name}: register 606 (decimals) reads {dp}, expected 0..3")
            self.decimals = dp
        if self.f4.check_units:
            units = self.m.read_registers(self.UNITS)[0]
            if units != 1:
                raise ChamberError(
                    f"{self.name}: register 901 reads {units} (0 = °F); set the controller to °C before a run"
                )

    # ---- values -------------------------------------------------------------------------------------
    def _dp(self) -> int:
        if self.decimals is None:
            self.connect()
        return int(self.decimals or 0)

    def _decode(self, raw: int) -> float:
        signed = raw - 0x10000 if raw & 0x8000 else raw
        return signed * 10.0 ** (-self._dp())

    def _encode(self, celsius: float) -> int:
        counts = round(celsius * 10 ** self._dp())
        if not -32768 <= counts <= 32767:
            raise ChamberError(f"{self.name}: {celsius:g} °C does not fit a 16-bit register at {self._dp()} decimals")
        return counts & 0xFFFF

    def _check(self) -> None:
        if self._closed:
            raise ChamberLinkError(f"{self.name}: driver is closed")

    # ---- Chamber --------------------------------------------------------------------------------------
    def read(self) -> ChamberReading:
        """PV, SP, input error (101) and profile state (200); the run event if wired."""
        self._check()
        i = self.f4.loop - 1
        pv = self._decode(self.m.read_registers(self.PV[i], function=self.f4.pv_function)[0])
        sp = self._decode(self.m.read_registers(self.SP[i])[0])
        error = self.m.read_registers(self.INPUT_ERROR)[0]
        state = self.m.read_registers(self.PROFILE_STATE)[0]
        running = None
        if self.f4.run_event is not None:
            running = bool(self.m.read_registers(2000 + 10 * (self.f4.run_event - 1))[0])
        return ChamberReading(
            setpoint=from_wire_celsius(sp),
            air=from_wire_celsius(pv),
            running=running,
            alarm=error != 0,
            detail=PROFILE_STATES.get(state, f"profile state {state}") + (", input error" if error else ""),
        )

    def set_setpoint(self, temperature: float) -> float:
        """Clamp, write the static set point (06), read it back (03); return the active set point, K."""
        self._check()
        target = to_wire_celsius(self.settings.clamp(temperature))
        reg = self.SP[self.f4.loop - 1]
        self.m.write_register(reg, self._encode(target))
        back = self._decode(self.m.read_registers(reg)[0])
        if abs(back - target) > max(self.settings.readback_tolerance, 0.51 * 10.0 ** (-self._dp())):
            raise ChamberError(f"{self.name}: set point {target:g} °C written, {back:g} °C read back")
        return from_wire_celsius(back)

    def start(self) -> None:
        """End any profile (1217 ← 1) so the static set point rules; the run event on if wired."""
        self._check()
        self.m.write_register(self.END_PROFILE, 1)
        if self.f4.run_event is not None:
            self.m.write_register(2000 + 10 * (self.f4.run_event - 1), 1)

    def stop(self) -> None:
        """End any profile (1217 ← 1); the run event off if wired."""
        self._check()
        self.m.write_register(self.END_PROFILE, 1)
        if self.f4.run_event is not None:
            self.m.write_register(2000 + 10 * (self.f4.run_event - 1), 0)

    def identify(self) -> str:
        """No identity register is documented beyond one client: the model, address and decimals."""
        return f"Watlow F4 (Modbus {self.m.framing.upper()} address {self.m.address}, {self._dp()} decimals)"

    def close(self) -> None:
        """Release the driver (the link stays with whoever opened it)."""
        self._closed = True


WordOrder = Literal["low_first", "high_first"]


@dataclass(frozen=True)
class WatlowF4TSettings:
    """Open points of the F4T native map (docs/protocols/chambers.md).

    Attributes
    ----------
    loop : int
        Control loop 1–4 (registers + 160 (n − 1)).
    word_order : {"low_first", "high_first"}
        Which register holds the low 16 bits of a float (the public client: low first; the manual: open).
    """

    loop: int = 1
    word_order: WordOrder = "low_first"

    def __post_init__(self) -> None:
        if not 1 <= self.loop <= 4:
            raise ValueError(f"Watlow F4T loop must be 1..4, got {self.loop!r}")
        if self.word_order not in ("low_first", "high_first"):
            raise ValueError(f"Watlow F4T word_order must be 'low_first' or 'high_first', got {self.word_order!r}")


class WatlowF4T:
    """Watlow F4T chamber controller, native register map (:class:`drivers.chamber.base.Chamber`)."""

    CONSTANT_SP = 2782
    PV = 2820
    PROFILE_STATE = 16568
    PROFILE_ACTION = 16566
    TERMINATE = 148
    DEVICE_STATUS = 90
    STATUS_OK = 138
    STATES = {149: "profile running", 146: "profile paused", 1783: "timed start"}

    def __init__(
        self,
        master: ModbusMaster,
        settings: ChamberSettings | None = None,
        f4t: WatlowF4TSettings | None = None,
        name: str = "Watlow F4T",
    ) -> None:
        self.m = master
        self.settings = settings or ChamberSettings()
        self.f4t = f4t or WatlowF4TSettings()
        self.name = name
        self._closed = False

    def connect(self) -> None:
        """Nothing to learn first: floats carry their own scale."""

    def _reg(self, base: int) -> int:
        return base + 160 * (self.f4t.loop - 1)

    def _words(self, value: float) -> list[int]:
        hi, lo = struct.unpack(">HH", struct.pack(">f", value))
        return [lo, hi] if self.f4t.word_order == "low_first" else [hi, lo]

    def _float(self, words: list[int]) -> float:
        lo, hi = (words[0], words[1]) if self.f4t.word_order == "low_first" else (words[1], words[0])
        value = struct.unpack(">f", struct.pack(">HH", hi, lo))[0]
        if not math.isfinite(value):
            raise ChamberLinkError(f"{self.name}: register pair {words} is not a finite float (word order?)")
        return float(value)

    def read(self) -> ChamberReading:
        """PV and constant SP of the loop, the profile state and the device status (90: 138 OK, 32 fail)."""
        if self._closed:
            raise ChamberLinkError(f"{self.name}: driver is closed")
        pv = self._float(self.m.read_registers(self._reg(self.PV), 2))
        sp = self._float(self.m.read_registers(self._reg(self.CONSTANT_SP), 2))
        state = self.m.read_registers(self.PROFILE_STATE)[0]
        status = self.m.read_registers(self.DEVICE_STATUS)[0]
        return ChamberReading(
            setpoint=from_wire_celsius(sp),
            air=from_wire_celsius(pv),
            running=None,
            alarm=status != self.STATUS_OK,
            detail=self.STATES.get(state, "constant")
            + ("" if status == self.STATUS_OK else f", device status {status}"),
        )

    def set_setpoint(self, temperature: float) -> float:
        """Clamp, write the constant set point as a float pair (16), read it back (03)."""
        if self._closed:
            raise ChamberLinkError(f"{self.name}: driver is closed")
        target = to_wire_celsius(self.settings.clamp(temperature))
        reg = self._reg(self.CONSTANT_SP)
        self.m.write_registers(reg, self._words(target))
        back = self._float(self.m.read_registers(reg, 2))
        if abs(back - target) > self.settings.readback_tolerance:
            raise ChamberError(f"{self.name}: set point {target:g} °C written, {back:g} °C read back")
        return from_wire_celsius(back)

    def start(self) -> None:
        """Terminate any profile so the constant set point rules (action 16566 ← 148)."""
        self.m.write_register(self.PROFILE_ACTION, self.TERMINATE)

    def stop(self) -> None:
        """Terminate any profile (action 16566 ← 148)."""
        self.m.write_register(self.PROFILE_ACTION, self.TERMINATE)

    def identify(self) -> str:
        """The model and address (no identity register used)."""
        return f"Watlow F4T (Modbus {self.m.framing.upper()} address {self.m.address}, loop {self.f4t.loop})"

    def close(self) -> None:
        """Release the driver."""
        self._closed = True

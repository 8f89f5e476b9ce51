"""The Modbus register map of the tablebench turntable controller — the ONE place it is defined.

Addresses are **0-based, as on the wire** (the PDU address field). Vendor manuals and some HMI tools
number holding registers from 40001 and input registers from 30001 (1-based, with a type prefix): holding
register address 25 here is "40026" there. Never add or subtract 1 anywhere else in the code.

Floating-point values are IEEE-754 **float64 across 4 consecutive registers**. Each register holds 16 bits
big-endian (Modbus standard); the *word order* is configurable per controller: ``"big"`` puts the most
significant word first (ABCD…), ``"little"`` the least significant word first. float64 rather than the
common float32 because float32 radians resolve only ≈0.8 arcsec at ten unwrapped turns (worse than an
arcsec-class table) and would make wire commands differ from in-process ones. :func:`pack_float32` /
:func:`unpack_float32` are provided for peripherals that use two-register floats (e.g. thermal chambers).

Holding registers (function codes 3 read, 6/16 write) — commands::

    addr  regs  name               content
    0     12    POSITION_SETPOINT  float64 × 3: absolute gimbal angles (outer, middle, inner), rad
    12    12    RATE_SETPOINT      float64 × 3: gimbal rates (outer, middle, inner), rad/s, signed
    24    1     COMMAND_AXIS       axis for SPIN (0 outer, 1 middle, 2 inner)
    25    1     COMMAND            execute register: 1 MOVE (all three axes to POSITION_SETPOINT: each axis
                                   in position mode), 2 SPIN (COMMAND_AXIS to its RATE_SETPOINT: that axis in
                                   rate mode), 3 STOP (all axes to rest under control), 4 CLEAR_FAULT
    26    1     HEARTBEAT          counter; any write feeds the controller's watchdog
    27    1     FAULT_RESET        write 1 to reset a latched fault (same as COMMAND = 4)

The per-axis mode is implied by the command (MOVE, SPIN, STOP) rather than written separately (the
set-points are only latched when COMMAND is written, so no half-written demand is ever acted on); the mode
of each axis is read back in MODE. A write that includes COMMAND executes after the rest of that write.
A refused command is answered with Modbus exception 3 (ILLEGAL DATA VALUE: out of
limits / bad command) or 4 (SERVER DEVICE FAILURE: a fault is latched); the reason is in LAST_REJECT.

Input registers (function code 4) — state::

    addr  regs  name               content
    0     4     TIME               float64 controller time stamp, s (bench time)
    4     12    ANGLES             float64 × 3 reported gimbal angles, rad (unwrapped)
    16    12    RATES              float64 × 3 reported gimbal rates, rad/s
    28    1     STATUS             drivers.protocols.TableStatus bits
    29    1     FAULT_CODE         drivers.protocols.FaultCode of the latched fault (0 none)
    30    3     MODE               drivers.protocols.AxisMode per axis
    33    1     LAST_REJECT        FaultCode of the last refused command (0 none)
    34    1     HEARTBEAT_ECHO     last HEARTBEAT value written
    40    48    LIMITS             per axis (outer, middle, inner) 4 × float64: rate_max (rad/s),
                                   accel_max (rad/s²), position_min, position_max (rad; NaN = continuous)
"""

from __future__ import annotations

import enum
import struct
from collections.abc import Sequence
from typing import Literal

WordOrder = Literal["big", "little"]

# ---- holding registers ---------------------------------------------------------------------------------------
HR_POSITION_SETPOINT = 0
HR_RATE_SETPOINT = 12
HR_COMMAND_AXIS = 24
HR_COMMAND = 25
HR_HEARTBEAT = 26
HR_FAULT_RESET = 27
HR_COUNT = 28

# ---- input registers -----------------------------------------------------------------------------------------
IR_TIME = 0
IR_ANGLES = 4
IR_RATES = 16
IR_STATUS = 28
IR_FAULT_CODE = 29
IR_MODE = 30
IR_LAST_REJECT = 33
IR_HEARTBEAT_ECHO = 34
IR_STATE_COUNT = 35  # registers 0..34: one read gives a whole TableState
IR_LIMITS = 40
IR_LIMITS_COUNT = 48
IR_COUNT = IR_LIMITS + IR_LIMITS_COUNT

F64_REGS = 4


class Command(enum.IntEnum):
    """Values of the COMMAND (execute) holding register."""

    NONE = 0
    MOVE = 1
    SPIN = 2
    STOP = 3
    CLEAR_FAULT = 4


def _check_order(word_order: str) -> None:
    if word_order not in ("big", "little"):
        raise ValueError(f"float word order must be 'big' or 'little', got {word_order!r}")


def pack_float64(values: Sequence[float] | float, word_order: WordOrder = "big") -> list[int]:
    """float64 value(s) → registers (4 per value) in the given word order."""
    _check_order(word_order)
    vals = [float(values)] if isinstance(values, (int, float)) else [float(v) for v in values]
    regs: list[int] = []
    for v in vals:
        words = list(struct.unpack(">4H", struct.pack(">d", v)))
        regs.extend(words if word_order == "big" else words[::-1])
    return regs


def unpack_float64(registers: Sequence[int], word_order: WordOrder = "big") -> list[float]:
    """Registers (multiple of 4) → float64 values."""
    _check_order(word_order)
    if len(registers) % F64_REGS:
        raise ValueError(f"float64 needs a multiple of 4 registers, got {len(registers)}")
    out: list[float] = []
    for i in range(0, len(registers), F64_REGS):
        words = [int(r) & 0xFFFF for r in registers[i : i + F64_REGS]]
        if word_order == "little":
            words = words[::-1]
        out.append(struct.unpack(">d", struct.pack(">4H", *words))[0])
    return out


def pack_float32(values: Sequence[float] | float, word_order: WordOrder = "big") -> list[int]:
    """float32 value(s) → registers (2 per value) in the given word order."""
    _check_order(word_order)
    vals = [float(values)] if isinstance(values, (int, float)) else [float(v) for v in values]
    regs: list[int] = []
    for v in vals:
        words = list(struct.unpack(">2H", struct.pack(">f", v)))
        regs.extend(words if word_order == "big" else words[::-1])
    return regs


def unpack_float32(registers: Sequence[int], word_order: WordOrder = "big") -> list[float]:
    """Registers (multiple of 2) → float32 values (as Python floats)."""
    _check_order(word_order)
    if len(registers) % 2:
        raise ValueError(f"float32 needs an even number of registers, got {len(registers)}")
    out: list[float] = []
    for i in range(0, len(registers), 2):
        words = [int(r) & 0xFFFF for r in registers[i : i + 2]]
        if word_order == "little":
            words = words[::-1]
        out.append(struct.unpack(">f", struct.pack(">2H", *words))[0])
    return out

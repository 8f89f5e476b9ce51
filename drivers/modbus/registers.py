"""Register codecs for Modbus devices: IEEE-754 floats across 16-bit registers, in either word order.

The turntable's register *map* is data, not code: ``drivers/modbus/maps/tablebench.yaml`` (the shipped
tablebench controller map, loaded and validated by :mod:`drivers.modbus.register_map`; a PLC with another layout
gets another file). This module keeps the float codecs shared by peripherals (e.g. thermal chambers, which
commonly use two-register float32).

Each register holds 16 bits big-endian (Modbus standard); the *word order* is configurable per device:
``"big"`` puts the most significant word first (ABCD…), ``"little"`` the least significant word first.
"""

from __future__ import annotations

import struct
from collections.abc import Sequence
from typing import Literal

WordOrder = Literal["big", "little"]
F64_REGS = 4


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

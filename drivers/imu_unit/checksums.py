"""Checksums of inertial-unit frames, vectorised over frames (rows of a 2-D byte array).

A CRC is described by the catalogue parameters (Rocksoft/Williams model, as in the "Catalogue of parametrised
CRC algorithms"): width, polynomial, initial value, input/output reflection and final XOR. The engine is
table-driven and loops over the byte *positions* of a frame (a few dozen), each step a 256-entry table lookup
vectorised over all frames at once — never over frames in Python.

Presets (check values for the ASCII string ``"123456789"``):

=====================  =====  ==========  ==========  =====  ==========  ==========
name                   width  poly        init        refl   xorout      check
=====================  =====  ==========  ==========  =====  ==========  ==========
crc-32/mpeg-2          32     0x04C11DB7  0xFFFFFFFF  no     0           0x0376E6E7
crc-16/ccitt-false     16     0x1021      0xFFFF      no     0           0x29B1
crc-32 (zlib)          32     0x04C11DB7  0xFFFFFFFF  yes    0xFFFFFFFF  0xCBF43926
=====================  =====  ==========  ==========  =====  ==========  ==========

Simple sums (:data:`SUM_KINDS`), for units that use no CRC:

=================  =====  ===============================================================================
name               bytes  value
=================  =====  ===============================================================================
``sum8``           1      sum of the covered bytes mod 256 (KVH built-in-test frames)
``sum8-neg``       1      (−sum of the covered bytes) mod 256: the covered bytes plus the checksum sum to 0
                          (Xsens Xbus)
``sum16``          2      sum of the covered bytes mod 65536
``sum16-words``    2      sum of the covered bytes taken as big-endian 16-bit words, mod 65536
                          (Epson M-G3xx UART burst, Honeywell HG4930 with ``-le``)
``sum16-words-le`` 2      the same with little-endian words
=================  =====  ===============================================================================

A word sum over an odd number of covered bytes is an error of the description (the reader refuses it).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

PRESETS: dict[str, dict[str, int | bool]] = {
    "crc-32/mpeg-2": {
        "width": 32,
        "poly": 0x04C11DB7,
        "init": 0xFFFFFFFF,
        "refin": False,
        "refout": False,
        "xorout": 0,
    },
    "crc-16/ccitt-false": {"width": 16, "poly": 0x1021, "init": 0xFFFF, "refin": False, "refout": False, "xorout": 0},
    "crc-32": {
        "width": 32,
        "poly": 0x04C11DB7,
        "init": 0xFFFFFFFF,
        "refin": True,
        "refout": True,
        "xorout": 0xFFFFFFFF,
    },
    "crc-16/xmodem": {"width": 16, "poly": 0x1021, "init": 0, "refin": False, "refout": False, "xorout": 0},
    "crc-8": {"width": 8, "poly": 0x07, "init": 0, "refin": False, "refout": False, "xorout": 0},
}


SUM_KINDS: dict[str, int] = {"sum8": 8, "sum8-neg": 8, "sum16": 16, "sum16-words": 16, "sum16-words-le": 16}
"""The simple sums by name → width in bits (see the module docstring)."""


def _reflect(v: int, width: int) -> int:
    return int(f"{v:0{width}b}"[::-1], 2)


@dataclass(frozen=True)
class CrcSpec:
    """A parametrised CRC (catalogue model) or one of the simple sums (:data:`SUM_KINDS`)."""

    algorithm: str
    width: int = 0
    poly: int = 0
    init: int = 0
    refin: bool = False
    refout: bool = False
    xorout: int = 0

    @classmethod
    def named(cls, name: str) -> CrcSpec:
        """A preset by catalogue name (``crc-32/mpeg-2``, ``crc-16/ccitt-false``, ``sum8``, …)."""
        if name in SUM_KINDS:
            return cls(name, width=SUM_KINDS[name])
        p = PRESETS[name]
        return cls(
            name, int(p["width"]), int(p["poly"]), int(p["init"]), bool(p["refin"]), bool(p["refout"]), int(p["xorout"])
        )

    @property
    def nbytes(self) -> int:
        """Bytes of the checksum field."""
        return self.width // 8


class CrcEngine:
    """Table-driven CRC of every row of a (k, m) uint8 array (vectorised over rows).

    The register is kept MSB-first (a reflected CRC is computed on bit-reversed input bytes and the result
    reflected), which keeps one code path for every width that is a multiple of 8.
    """

    def __init__(self, spec: CrcSpec) -> None:
        self.spec = spec
        w = spec.width
        if spec.algorithm not in SUM_KINDS and (w not in (8, 16, 32) or not 0 <= spec.poly < (1 << w)):
            raise ValueError(f"CRC width must be 8, 16 or 32 and poly < 2^width (got width {w}, poly {spec.poly:#x})")
        self._dtype = {8: np.uint8, 16: np.uint16, 32: np.uint32}.get(w, np.uint32)
        self._fixed: dict[int, tuple[NDArray[np.unsignedinteger], int]] = {}
        self._offsets: dict[int, NDArray[np.intp]] = {}
        self._flat: dict[int, NDArray[np.unsignedinteger]] = {}
        if spec.algorithm in SUM_KINDS:
            return
        top = 1 << (w - 1)
        mask = (1 << w) - 1
        table = np.zeros(256, dtype=np.uint64)
        for b in range(256):
            crc = b << (w - 8)
            for _ in range(8):
                crc = ((crc << 1) ^ spec.poly) & mask if crc & top else (crc << 1) & mask
            table[b] = crc
        self.table = table.astype(self._dtype)
        self._rev = np.array([_reflect(b, 8) for b in range(256)], dtype=np.uint8)

    def _position_tables(self, m: int) -> tuple[NDArray[np.unsignedinteger], int]:
        """Per-position tables of a fixed-length message: (m, 256) contributions and the constant part.

        A CRC without reflection of a fixed-length message is affine in its bytes: with init 0 it is linear,
        so crc(d) = crc(0…0) ⊕ ⊕_j T_j[d_j], where T_j[v] is the zero-init CRC of byte v followed by
        m − 1 − j zero bytes. Reflected input is handled by bit-reversing the table index.
        """
        cached = self._fixed.get(m)
        if cached is not None:
            return cached
        s, dt = self.spec, self._dtype
        w = s.width
        tables = np.empty((m, 256), dtype=dt)
        r = self.table.copy()  # zero-init register after one byte v
        top = dt(w - 8)
        eight = dt(8)
        for j in range(m - 1, -1, -1):
            tables[j] = r
            if w == 8:
                r = self.table[r]
            else:
                r = (r << eight) ^ self.table[(r >> top).astype(np.uint8)]
        if s.refin:
            tables = tables[:, self._rev]
        const = dt(s.init)
        for _ in range(m):  # the init value pushed through m zero bytes
            const = self.table[const] if w == 8 else (const << eight) ^ self.table[np.uint8(const >> top)]
        self._fixed[m] = (tables, int(const))
        self._offsets[m] = (np.arange(m) * 256).astype(np.uint16 if m <= 256 else np.intp)
        self._flat[m] = tables.ravel()
        return tables, int(const)

    def __call__(self, data: NDArray[np.uint8]) -> NDArray[np.unsignedinteger]:
        """Checksum of every row of ``data`` (shape (k, m) or (m,)); returns (k,) of the CRC's width.

        One gather of the per-position tables and one XOR reduction over the row (no loop over bytes).
        """
        d = np.atleast_2d(np.asarray(data, dtype=np.uint8))
        s = self.spec
        if s.algorithm in SUM_KINDS:
            return _simple_sum(s.algorithm, d)
        if d.shape[1] <= 512:
            tables, const = self._position_tables(d.shape[1])
            flat, offs = self._flat[d.shape[1]], self._offsets[d.shape[1]]
            contrib = flat[np.ascontiguousarray(d.T) + offs[:, None]]  # (m, k): reduce over the contiguous axis 0
            crc = np.bitwise_xor.reduce(contrib, axis=0) ^ self._dtype(const)
            crc = crc.astype(self._dtype)
            if s.refout:
                crc = _reflect_vec(crc, s.width)
            if s.xorout:
                crc = crc ^ self._dtype(s.xorout)
            return crc
        return self._bytewise(d)

    def _bytewise(self, d: NDArray[np.uint8]) -> NDArray[np.unsignedinteger]:
        """The classic byte-at-a-time table loop (vectorised over rows); reference for long messages."""
        s = self.spec
        if s.refin:
            d = self._rev[d]
        dt = self._dtype
        w = s.width
        crc = np.full(d.shape[0], s.init, dtype=dt)
        shift_hi = dt(w - 8)
        eight = dt(8)
        table = self.table
        if w == 8:
            for j in range(d.shape[1]):
                crc = table[crc ^ d[:, j]]
        else:
            for j in range(d.shape[1]):
                idx = (crc >> shift_hi).astype(np.uint8) ^ d[:, j]
                crc = (crc << eight) ^ table[idx]
        if s.refout:
            crc = _reflect_vec(crc, w)
        if s.xorout:
            crc = crc ^ dt(s.xorout)
        return crc


def _simple_sum(kind: str, d: NDArray[np.uint8]) -> NDArray[np.unsignedinteger]:
    """One of :data:`SUM_KINDS` of every row of ``d`` (k, m)."""
    if kind.startswith("sum16-words"):
        if d.shape[1] % 2:
            raise ValueError(f"{kind} needs an even number of covered bytes, got {d.shape[1]}")
        w = d.astype(np.uint64)
        hi, lo = (w[:, 0::2], w[:, 1::2]) if kind == "sum16-words" else (w[:, 1::2], w[:, 0::2])
        return ((hi * 256 + lo).sum(axis=1, dtype=np.uint64) & 0xFFFF).astype(np.uint16)
    total = d.sum(axis=1, dtype=np.uint64)
    if kind == "sum16":
        return (total & 0xFFFF).astype(np.uint16)
    if kind == "sum8-neg":
        total = np.uint64(0x100) - (total & np.uint64(0xFF))
    return (total & 0xFF).astype(np.uint8)


def _reflect_vec(v: NDArray[np.unsignedinteger], width: int) -> NDArray[np.unsignedinteger]:
    out = np.zeros_like(v)
    x = v.copy()
    one = v.dtype.type(1)
    for _ in range(width):
        out = (out << one) | (x & one)
        x = x >> one
    return out


def crc32_mpeg2(data: bytes | NDArray[np.uint8]) -> int:
    """CRC-32/MPEG-2 of one byte string (convenience; check value 0x0376E6E7)."""
    return int(CrcEngine(CrcSpec.named("crc-32/mpeg-2"))(np.frombuffer(bytes(data), np.uint8))[0])

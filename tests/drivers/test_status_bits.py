"""TableStatus's bits as plain integers are defined once, in drivers.protocols (next to the flags), and every
driver and simulator that builds a status bit by bit takes them from there."""

from __future__ import annotations

import re
from pathlib import Path

import drivers.protocols as protocols
from drivers.protocols import TableStatus

ROOT = Path(__file__).resolve().parents[2]


def test_every_flag_has_its_plain_integer_and_nothing_else_is_named_so() -> None:
    flags = {f"STATUS_{m.name}": int(m) for m in TableStatus if m.name and m is not TableStatus.NONE}
    ints = {k: v for k, v in vars(protocols).items() if k.startswith("STATUS_")}
    assert ints == flags
    assert all(type(v) is int for v in ints.values())  # plain ints: an IntFlag's | runs Python code


def test_the_bits_are_not_restated_outside_protocols() -> None:
    restated = re.compile(r"int\(\s*TableStatus\.|TableStatus\.[A-Z_]+\.value")
    bad = [
        str(p.relative_to(ROOT))
        for pkg in ("drivers", "benches", "procedures", "analysis", "core")
        for p in sorted((ROOT / pkg).rglob("*.py"))
        if p.name != "protocols.py" and restated.search(p.read_text(encoding="utf-8"))
    ]
    assert bad == [], "use drivers.protocols.STATUS_* instead: " + ", ".join(bad)

"""Write one benchmark's section of ``benchmarks/RESULTS.md`` (other sections are kept).

Each benchmark script calls :func:`write_section` with its own name and a Markdown body; the section is
replaced between ``<!-- BEGIN name -->`` and ``<!-- END name -->`` markers, stamped with the date, the
machine (CPU count, Python, numpy) and the command that produced it.
"""

from __future__ import annotations

import datetime as _dt
import os
import platform
import re
import sys
from pathlib import Path

import numpy as np

RESULTS = Path(__file__).resolve().parent / "RESULTS.md"
HEADER = (
    "# Benchmark results\n\n"
    "Measured on this project's CI-class machine (2 cores). Every figure is a ratio against a reference "
    "measured in the same run (real time, or an independent library), never an absolute target in a test.\n"
    "Regenerate with `python -m benchmarks.run_all` (or one script, e.g. `python -m benchmarks.bench_noise`).\n"
)


def machine_line() -> str:
    """One line describing the machine and software of this run."""
    return (
        f"{_dt.datetime.now(_dt.timezone.utc).strftime('%Y-%m-%d %H:%M UTC')}, {os.cpu_count()} CPUs, "
        f"{platform.machine()}, Python {platform.python_version()}, numpy {np.__version__}"
    )


def write_section(name: str, title: str, body: str) -> None:
    """Replace (or append) the section ``name`` of RESULTS.md with ``title`` and ``body`` (Markdown)."""
    text = RESULTS.read_text(encoding="utf-8") if RESULTS.exists() else HEADER
    cmd = "python -m benchmarks." + Path(sys.argv[0]).stem if sys.argv and sys.argv[0] else ""
    block = f"<!-- BEGIN {name} -->\n## {title}\n\n_{machine_line()}; `{cmd}`_\n\n{body.rstrip()}\n<!-- END {name} -->"
    pattern = re.compile(rf"<!-- BEGIN {re.escape(name)} -->.*?<!-- END {re.escape(name)} -->", re.S)
    if pattern.search(text):
        text = pattern.sub(lambda _m: block, text)
    else:
        text = text.rstrip() + "\n\n" + block + "\n"
    RESULTS.write_text(text, encoding="utf-8")

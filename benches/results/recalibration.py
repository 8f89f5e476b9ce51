"""What the bench file says about the registry: the unit's configuration version and recalibration settings.

``unit.configuration`` (text, default "1"): a re-soldered, repaired or re-mounted unit is a new configuration,
and its history starts again (the registry keys a unit by serial number, model and configuration).

``recalibration:`` (optional section; ILAC-G24:2022 methods 1 and 2, see :mod:`benches.results.registry.stats`):

=====================  =====  =======  ==============================================================
key                    unit   default  meaning
=====================  =====  =======  ==============================================================
``initial_days``       d      365      the first interval (and the start of the staircase)
``min_days``           d      30       no interval shorter
``max_days``           d      1095     no interval longer
``extend``             1      1.5      method 1: factor after a calibration found in tolerance (> 1)
``reduce``             1      0.5      method 2: factor after one found out of tolerance (< 1)
``drift_allowance_U``  U      1.0      method 2: drift allowed between calibrations, in last U (k = 2)
=====================  =====  =======  ==============================================================

The bench parser (:mod:`benches.bench_config`) validates both with these functions (file:line messages);
the registry reads them from the bench text recorded with each run (``docs/registry.md``).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

from core.yaml_source import ConfigError, SourceMap, check_keys, get_mapping, get_number, load_yaml_text

DEFAULT_CONFIGURATION = "1"
KEYS = ("initial_days", "min_days", "max_days", "extend", "reduce", "drift_allowance_U")


@dataclass(frozen=True)
class IntervalSettings:
    """Recalibration interval settings, days (see the module docstring); ``source`` says where they come from."""

    initial_days: float = 365.0
    min_days: float = 30.0
    max_days: float = 1095.0
    extend: float = 1.5
    reduce: float = 0.5
    drift_allowance_U: float = 1.0  # noqa: N815 - U is the symbol
    source: str = "defaults (no recalibration section in the bench file)"


def parse_recalibration(d: Any, smap: SourceMap) -> IntervalSettings:
    """The ``recalibration`` section (None: defaults)."""
    if d is None:
        return IntervalSettings()
    p = ("recalibration",)
    d = get_mapping(d, smap, p)
    check_keys(d, smap, p, list(KEYS))
    base = IntervalSettings()
    v = {k: get_number(d, smap, p, k, getattr(base, k), minimum=0, exclusive_minimum=True) for k in KEYS}
    if not v["min_days"] <= v["initial_days"] <= v["max_days"]:
        raise smap.error(p + ("initial_days",), "must lie within [min_days, max_days]")
    if v["extend"] < 1:
        raise smap.error(p + ("extend",), f"{v['extend']:g} must be ≥ 1 (the interval grows after a good finding)")
    if v["reduce"] > 1:
        raise smap.error(p + ("reduce",), f"{v['reduce']:g} must be ≤ 1 (the interval shrinks after a bad finding)")
    line = smap.line(p)
    where = f"{smap.file}:{line}" if line else f"{smap.file} (recalibration)"
    return IntervalSettings(**v, source=where)


def parse_configuration(unit: Any, smap: SourceMap) -> str:
    """``unit.configuration`` as text (numbers allowed: 2 → "2"); default "1"."""
    if not isinstance(unit, dict) or unit.get("configuration") is None:
        return DEFAULT_CONFIGURATION
    v = unit["configuration"]
    if isinstance(v, bool) or not isinstance(v, str | int | float) or not str(v).strip():
        raise smap.error(("unit", "configuration"), f"expected a configuration version (text or number), got {v!r}")
    return str(int(v)) if isinstance(v, float) and v.is_integer() else str(v).strip()


def from_bench_text(text: str, file: str | Path = "bench.yaml") -> tuple[str, IntervalSettings]:
    """(configuration, settings) of a bench file's text; defaults when the text is empty or does not parse
    (the run's own bench was checked when it ran)."""
    if not text.strip():
        return DEFAULT_CONFIGURATION, IntervalSettings()
    try:
        data, smap = load_yaml_text(text, str(file))
        if not isinstance(data, dict):
            return DEFAULT_CONFIGURATION, IntervalSettings()
        return parse_configuration(data.get("unit"), smap), parse_recalibration(data.get("recalibration"), smap)
    except ConfigError:
        return DEFAULT_CONFIGURATION, IntervalSettings()


__all__ = ["DEFAULT_CONFIGURATION", "IntervalSettings", "from_bench_text", "parse_configuration",
           "parse_recalibration"]

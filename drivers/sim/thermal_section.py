"""The ``simulation.thermal`` section of a bench file: the simulated unit's errors as polynomials in its own
temperature (:class:`~drivers.sim.thermal_config.ThermalTruth`, docs/methods/thermal.md). Display units in the
key names; each list holds one row per power k = 1, 2, … of (T − T_ref), per °C^k (= per K^k).

```yaml
thermal:
  reference_c: 20                          # T_ref: the accelerometer:/gyro: truth holds there
  accelerometer:
    bias_ug_per_c: [[30, -20, 25], [0.3, -0.2, 0.25]]    # k = 1 (µg/°C), k = 2 (µg/°C²)
    scale_ppm_per_c: [[5, -4, 6]]
    misalignment_arcsec_per_c: [[0.5, -0.4, 0.3, 0.6, -0.5, 0.4]]   # τ_xy τ_xz τ_yx τ_yz τ_zx τ_zy
    bias_ug_per_c_per_min: [0, 0, 0]        # the dT/dt term (lag, hysteresis)
  gyro:
    bias_dph_per_c: [[0.05, -0.04, 0.03]]
    scale_ppm_per_c: [[10, -8, 12]]
    misalignment_arcsec_per_c: [[1.0, -0.8, 0.6, 1.2, -1.0, 0.8]]
    bias_dph_per_c_per_min: [0, 0, 0]
```
"""

from __future__ import annotations

import math
from typing import Any

from analysis.units import ARCSEC, DEG_PER_HOUR, PPM, UG, celsius_to_kelvin
from core.yaml_source import KeyPath, SourceMap, check_keys, get_number, get_vector
from core.yaml_source import get_section as _section
from drivers.sim.thermal_config import ThermalTruth, TriadThermal

MAX_ORDER = 5
"""Highest power of (T − T_ref) a bench file may give."""
_TRIADS = {
    "accelerometer": (UG, "ug"),
    "gyro": (DEG_PER_HOUR, "dph"),
}


def _rows(d: dict, smap: SourceMap, p: KeyPath, key: str, width: int, unit: float) -> tuple[tuple[float, ...], ...]:
    """A list of rows of ``width`` finite numbers (row k−1: power k), × ``unit``."""
    v = d.get(key)
    if v is None:
        return ()
    example = "[[" + ", ".join(["0"] * width) + "]]"
    if not isinstance(v, list) or not 1 <= len(v) <= MAX_ORDER:
        raise smap.error(p + (key,), f"expected 1 to {MAX_ORDER} rows (one per power of T − T_ref) like {example}")
    out = []
    for k, row in enumerate(v):
        ok = isinstance(row, list) and len(row) == width
        ok = ok and all(isinstance(x, int | float) and not isinstance(x, bool) and math.isfinite(x) for x in row)
        if not ok:
            msg = f"expected a row of {width} finite numbers like {example[1:-1]}, got {row!r}"
            raise smap.error(p + (key, k), msg)
        out.append(tuple(float(x) * unit for x in row))
    return tuple(out)


def _triad(d: dict | None, smap: SourceMap, p: KeyPath, unit: float, stem: str) -> TriadThermal:
    if d is None:
        return TriadThermal()
    rate_key = f"bias_{stem}_per_c_per_min"
    keys = [f"bias_{stem}_per_c", "scale_ppm_per_c", "misalignment_arcsec_per_c", rate_key]
    check_keys(d, smap, p, keys)
    rate = get_vector(d, smap, p, rate_key, 3, [0.0, 0.0, 0.0])
    return TriadThermal(
        bias=_rows(d, smap, p, keys[0], 3, unit),  # type: ignore[arg-type]
        scale=_rows(d, smap, p, keys[1], 3, PPM),  # type: ignore[arg-type]
        misalignment=_rows(d, smap, p, keys[2], 6, ARCSEC),
        bias_rate=tuple(float(x) * unit * 60.0 for x in rate),  # type: ignore[arg-type]  per (K/min) → per K/s
    )


def parse_thermal(d: dict[str, Any], smap: SourceMap, p: KeyPath) -> ThermalTruth | None:
    """``simulation.thermal`` → :class:`ThermalTruth` (SI), None when absent."""
    td = _section(d, smap, p, "thermal", required=False)
    if td is None:
        return None
    tp = p + ("thermal",)
    check_keys(td, smap, tp, ["reference_c", *_TRIADS])
    ref = get_number(td, smap, tp, "reference_c", 23.0, minimum=-60, maximum=150)
    triads = {
        name: _triad(_section(td, smap, tp, name, required=False), smap, tp + (name,), unit, stem)
        for name, (unit, stem) in _TRIADS.items()
    }
    return ThermalTruth(reference=celsius_to_kelvin(ref), accel=triads["accelerometer"], gyro=triads["gyro"])

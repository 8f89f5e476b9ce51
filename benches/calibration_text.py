"""The calibration result (``calibration.json`` content) as a readable terminal table."""

from __future__ import annotations

from typing import Any


def format_result(result: dict[str, Any]) -> str:
    """A readable table of a calibration result (as written by :func:`benches.identify.write_calibration`)."""
    lines = [f"{'param':8s} {'value':>12s} {'1σ':>10s} {'unit':7s} {'err/σ':>7s}  note"]
    truth = result.get("truth") or {}
    for name in result["parameter_names"]:
        p = result["parameters"][name]
        e = truth.get("error_sigma", {}).get(name)
        note = "" if p["identifiable"] else "NOT IDENTIFIED (prior-dominated; do not use)"
        lines.append(
            f"{name:8s} {p['display_value']:12.4f} {p['display_sigma']:10.4f} {p['display_unit']:7s} "
            f"{'' if e is None else f'{e:7.2f}':>7s}  {note}"
        )
    info = result["information"]
    lines.append(f"information rank {info['rank']}/18, condition {info['condition']:.3g}; method {result['method']}")
    if truth:
        lines.append(f"NEES {truth['nees']:.2f} over {truth['dof']} identified states (simulator truth)")
    else:
        lines.append("no simulator truth in the recording (a real bench): errors against truth not computed")
    lines += [f"warning: {w}" for w in result.get("warnings", [])]
    return "\n".join(lines)

"""The analyses a certificate or a noise report quotes (``RUN/noise/noise.json``, ``periodic/periodic.json``,
``drift/drift.json``, formats in the analysis commands' docs) as rows of text.

One rule for every ±: the expanded uncertainty U = 2σ (k = 2) to two significant digits and the value to the same
decimal (GUM 7.2.6, :func:`benches.certificate.content.format_with_uncertainty`, as in the results table); one
unit per quantity: an analysis file's SI values (m/s², rad/s) are shown in the certificate's display units
(µg, °/h; :mod:`analysis.units`).
"""

from __future__ import annotations

import math
from typing import Any

from analysis.units import display_unit, from_display

from .content import format_with_uncertainty


def _fmt(x: Any) -> str:
    try:
        return f"{float(x):.4g}"
    except (TypeError, ValueError):
        return str(x)


def _number(x: Any) -> float | None:
    """A finite float, else None (an analysis file's missing or non-numeric entry)."""
    if isinstance(x, bool):
        return None
    try:
        v = float(x)
    except (TypeError, ValueError):
        return None
    return v if math.isfinite(v) else None


def _pm(value: Any, sigma: Any, unit: str) -> str:
    """``value ± U unit (U, k = 2)`` with U = 2σ to two significant digits and the value to the same decimal
    (GUM 7.2.6, the results table's rule: :func:`format_with_uncertainty`); the value alone when σ is absent."""
    v, s = _number(value), _number(sigma)
    if v is None:
        return f"{value} {unit}".strip()
    if s is None or s <= 0:
        return f"{v:.4g} {unit}".strip()
    v_txt, u_txt = format_with_uncertainty(v, 2.0 * s)
    return f"{v_txt} ± {u_txt} {unit} (U, k = 2)".replace("  ", " ")


_SI_KIND = {"m/s^2": "acceleration", "m/s²": "acceleration", "rad/s": "gyro_bias"}
"""An analysis file's SI unit of a channel → the quantity kind whose display unit the certificate uses (µg,
°/h): the results table and the analyses in one unit per quantity (``analysis.units``)."""


def _display(channel: str, unit: str | None) -> tuple[str, float]:
    """(display unit, SI per display unit) for an analysis channel's values given in ``unit`` (default: the
    channel's SI unit); a unit the certificate does not know is kept as it is (factor 1)."""
    u = unit or _si_unit(channel)
    kind = _SI_KIND.get(u)
    if kind is None:
        return u, 1.0
    return display_unit(kind), from_display(kind, 1.0)


def _si_unit(channel: str) -> str:
    """SI unit of an analysis channel's values (analysis JSON files are SI)."""
    return "rad/s" if channel.startswith("gyro") else "m/s²" if channel.startswith("accel") else "(SI)"


def noise_rows(ch: str, c: dict[str, Any]) -> list[dict[str, str]]:
    rows = []
    for term, t in sorted((c.get("terms_display") or c.get("terms") or {}).items()):
        t = t or {}
        rows.append({"channel": ch, "item": str(term), "value": _pm(t.get("value"), t.get("sigma"), t.get("unit", ""))})
    return rows


def _periodic_rows(ch: str, c: dict[str, Any]) -> list[dict[str, str]]:
    rows = []
    for i, t in enumerate(c.get("terms") or []):
        unit, si = _display(ch, t.get("amplitude_unit") or c.get("unit"))
        amp, amp_s = _number(t.get("amplitude")), _number(t.get("amplitude_sigma"))
        amp_txt = _pm(None if amp is None else amp / si, None if amp_s is None else amp_s / si, unit)
        rows.append(
            {
                "channel": ch,
                "item": f"tone {i + 1}",
                "value": f"{_pm(t.get('frequency_hz'), t.get('frequency_sigma_hz'), 'Hz')}, amplitude {amp_txt}, "
                f"phase {_pm(t.get('phase_rad'), t.get('phase_sigma_rad'), 'rad')}",
            }
        )
    if "residual_rms_before" in c:
        unit, si = _display(ch, c.get("unit"))
        before, after = _number(c.get("residual_rms_before")), _number(c.get("residual_rms_after"))
        txt = " → ".join("—" if x is None else f"{x / si:.4g}" for x in (before, after))
        rows.append({"channel": ch, "item": "residual RMS", "value": f"{txt} {unit}"})
    return rows


def _drift_rows(ch: str, c: dict[str, Any]) -> list[dict[str, str]]:
    m = c.get("model") or {}
    unit, si = _display(ch, None)
    s2 = _number(m.get("sigma2"))
    sig = "—" if s2 is None or s2 < 0 else f"{math.sqrt(s2) / si:.4g} {unit}"
    rows = [
        {
            "channel": ch,
            "item": f"ARMA({m.get('p', '?')},{m.get('q', '?')})",
            "value": f"φ {[round(float(v), 4) for v in m.get('phi', [])]}, "
            f"θ {[round(float(v), 4) for v in m.get('theta', [])]}, innovation σ {sig}",
        }
    ]
    for name, t in sorted((c.get("tests") or {}).items()):
        t = t or {}
        rows.append(
            {
                "channel": ch,
                "item": str(name),
                "value": f"{_fmt(t.get('statistic'))} (threshold {_fmt(t.get('threshold'))}): {t.get('verdict', '')}",
            }
        )
    return rows


def analysis_rows(kind: str, data: dict[str, Any]) -> list[dict[str, str]]:
    """Summary rows of a noise / periodic / drift JSON (formats in the analysis commands' docs), in the
    certificate's display units (µg, °/h), every ± an expanded uncertainty U (k = 2) to the value's decimal."""
    rows: list[dict[str, str]] = []
    channels = data.get("channels", {}) if isinstance(data, dict) else {}
    each = {"noise": noise_rows, "periodic": _periodic_rows, "drift": _drift_rows}[kind]
    for ch in sorted(channels):
        rows += each(str(ch), channels[ch] or {})
    return rows


__all__ = ["analysis_rows", "noise_rows"]

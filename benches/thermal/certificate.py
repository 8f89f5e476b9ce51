"""The thermal calibration certificate: every parameter as a function of the unit's temperature, with U(k = 2)
(docs/methods/thermal.md, "The thermal certificate").

Built from a verified ``thermal_calibration.json`` (:mod:`benches.thermal.document`):

* the model: p(T) = Σ c_k (T − T_ref)^k per parameter, T_ref, the orders chosen by BIC, χ²/dof, and the
  **validity range** (the span of the plateau temperatures; ``tablebench correct`` refuses or warns outside);
* per parameter, the coefficients with U(k = 2);
* a table of every parameter at each plateau (the plateau's own estimate ± U) and of the model on a grid of
  temperatures across the validity range (value ± U, U from the coefficients' full covariance) — the
  "stated U" of the compensation at that temperature;
* the residual after compensation at each plateau (estimate − model, ± U);
* plots of each parameter against temperature: the model with its U(k = 2) band and the plateau estimates
  with their U bars.

Display units (one per quantity, as elsewhere): µg, ppm, arcsec, µg/g², mm, °/h; temperatures in °C.
The JSON twin holds the same numbers, SI.
"""

from __future__ import annotations

import datetime as _dt
import io
from pathlib import Path
from typing import Any

import numpy as np

from analysis.units import ARCSEC, CELSIUS_ZERO, DEG_PER_HOUR, MM, PPM, UG, UG_PER_G2
from benches.thermal.document import ThermalFile
from core.jsonio import write_json, write_text_atomic

GRID_STEP = 10.0
"""Spacing of the model table's temperatures, K (plus both ends of the validity range)."""
_KINDS = {  # name prefix → (kind, display unit, SI per display unit)
    "b": ("accelerometer bias", "µg", UG),
    "S": ("accelerometer scale factor", "ppm", PPM),
    "tau": ("accelerometer misalignment", "arcsec", ARCSEC),
    "d": ("accelerometer quadratic", "µg/g²", UG_PER_G2),
    "r": ("accelerometer size effect", "mm", MM),
    "gb": ("gyro bias", "°/h", DEG_PER_HOUR),
    "gS": ("gyro scale factor", "ppm", PPM),
    "gtau": ("gyro misalignment", "arcsec", ARCSEC),
}


def kind_of(name: str) -> tuple[str, str, float]:
    """(kind, display unit, SI per display unit) of a thermal-model parameter."""
    return _KINDS[name.split("_")[0]]


def grid_temperatures(lo: float, hi: float, step: float = GRID_STEP) -> np.ndarray:
    """Both ends of [lo, hi] (K) and the whole multiples of ``step`` °C inside."""
    inner = np.arange(np.ceil((lo - CELSIUS_ZERO) / step) * step, hi - CELSIUS_ZERO, step) + CELSIUS_ZERO
    return np.unique(np.concatenate([[lo], inner[inner > lo], [hi]]))


def certificate_content(tf: ThermalFile, issue_date: str | None = None) -> dict[str, Any]:
    """The certificate's numbers (SI) and texts: what the PDF prints and the JSON holds."""
    m = tf.model
    raw = tf.content
    grid = grid_temperatures(*m.temperature_range)
    values, u = m.evaluate(grid)
    plateaus = tf.estimates()
    residual = [
        (np.asarray(pl.x) - m.evaluate(pl.temperature, pl.rate)[0][0]).tolist() for pl in plateaus
    ]
    params = {}
    for p, name in enumerate(m.names):
        c, cov = m.parameter(name)
        kind, unit, si = kind_of(name)
        params[name] = {
            "kind": kind,
            "display_unit": unit,
            "order": int(m.orders[p]),
            "coefficients": c.tolist(),
            "U_coefficients": (2.0 * np.sqrt(np.diag(cov))).tolist(),
            "model_at_grid": values[:, p].tolist(),
            "U_model_at_grid": (2.0 * u[:, p]).tolist(),
            "plateau_values": [float(pl.x[p]) for pl in plateaus],
            "U_plateau_values": [float(2.0 * np.sqrt(pl.covariance[p, p])) for pl in plateaus],
            "residual_at_plateaus": [r[p] for r in residual],
        }
    return {
        "title": "Thermal calibration certificate",
        "issue_date": issue_date or _dt.datetime.now(_dt.UTC).date().isoformat(),
        "unit": raw.get("unit", {}),
        "bench": raw.get("bench", ""),
        "run": raw.get("run", ""),
        "recording_sha256": raw.get("recording_sha256", ""),
        "calibration_sha256": (raw.get("integrity") or {}).get("values_sha256", ""),
        "model": {
            "equation": "p(T) = sum_k c_k (T - T_ref)^k, T the unit's own temperature (its temperature channel)",
            "reference_K": m.reference,
            "validity_range_K": list(m.temperature_range),
            "order_selection": "BIC of the joint generalised least-squares fit (orders 0-3), held-out check",
            "chi2": m.chi2,
            "dof": m.dof,
            "coverage": "U = 2u (k = 2, about 95 %)",
            "outside_range": "tablebench correct refuses (default) or warns (--outside-range warn)",
        },
        "grid_K": grid.tolist(),
        "plateaus": [
            {"name": p["name"], "temperature_K": p["temperature_K"], "rate_K_per_s": p["rate_K_per_s"],
             "direction": p["direction"], "setpoint_K": p["setpoint_K"]}  # fmt: skip
            for p in tf.plateaus
        ],
        "parameters": params,
        "skipped": raw.get("skipped", []),
    }


def _plot(content: dict[str, Any], names: list[str]) -> bytes:
    """One figure: each parameter of ``names`` against temperature (model ± U band, plateaus ± U)."""
    import matplotlib  # lazy: matplotlib (--help time)

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt  # lazy: matplotlib (--help time)

    grid = np.asarray(content["grid_K"]) - CELSIUS_ZERO
    fine = np.linspace(grid[0], grid[-1], 60)
    tp = np.array([p["temperature_K"] for p in content["plateaus"]]) - CELSIUS_ZERO
    fig, axes = plt.subplots(1, len(names), figsize=(2.6 * len(names), 2.3), squeeze=False)
    for ax, name in zip(axes[0], names, strict=True):
        par = content["parameters"][name]
        si = kind_of(name)[2]
        c = np.asarray(par["coefficients"])
        ref = content["model"]["reference_K"] - CELSIUS_ZERO
        curve = np.polyval(c[::-1], fine - ref) / si
        band = np.interp(fine, grid, np.asarray(par["U_model_at_grid"]) / si)
        ax.fill_between(fine, curve - band, curve + band, color="tab:blue", alpha=0.25, lw=0, label="model ± U")
        ax.plot(fine, curve, color="tab:blue", lw=1.0)
        ax.errorbar(tp, np.asarray(par["plateau_values"]) / si, np.asarray(par["U_plateau_values"]) / si,
                    fmt="o", ms=3, color="k", capsize=2, label="plateau ± U")  # fmt: skip
        ax.set_title(f"{name} [{par['display_unit']}]", fontsize=8)
        ax.set_xlabel("unit temperature [°C]", fontsize=7)
        ax.tick_params(labelsize=6)
        ax.ticklabel_format(axis="y", useOffset=False)
    axes[0][0].legend(fontsize=6)
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=110)
    plt.close(fig)
    return buf.getvalue()


def _fmt(v: float, si: float) -> str:
    return f"{v / si:.4g}"


def parameter_rows(content: dict[str, Any], name: str) -> list[list[str]]:
    """Table rows of one parameter: each plateau (estimate ± U), then the model on the grid (value ± U)."""
    par = content["parameters"][name]
    si = kind_of(name)[2]
    rows = []
    for pl, v, uu, r in zip(content["plateaus"], par["plateau_values"], par["U_plateau_values"],
                            par["residual_at_plateaus"], strict=True):  # fmt: skip
        t = pl["temperature_K"] - CELSIUS_ZERO
        rows.append([f"plateau {t:.2f}", f"{_fmt(v, si)} ± {_fmt(uu, si)}", f"{_fmt(r, si)}"])
    for t, v, uu in zip(content["grid_K"], par["model_at_grid"], par["U_model_at_grid"], strict=True):
        rows.append([f"model {t - CELSIUS_ZERO:.2f}", f"{_fmt(v, si)} ± {_fmt(uu, si)}", ""])
    return rows


def _groups(names: list[str]) -> list[list[str]]:
    out: dict[str, list[str]] = {}
    for n in names:
        out.setdefault(kind_of(n)[0], []).append(n)
    return list(out.values())


def render_pdf(content: dict[str, Any]) -> bytes:
    """The certificate as PDF bytes."""
    from fpdf import FPDF, XPos, YPos  # lazy: fpdf (--help time)

    from benches.certificate.pdf import _font_dir  # lazy: fpdf, matplotlib (--help time)

    pdf = FPDF(orientation="P", unit="mm", format="A4")
    d = _font_dir()
    pdf.add_font("DejaVu", "", str(d / "DejaVuSans.ttf"))
    pdf.add_font("DejaVu", "B", str(d / "DejaVuSans-Bold.ttf"))
    pdf.set_margins(15, 15, 15)
    pdf.set_auto_page_break(True, margin=15)
    pdf.add_page()

    def line(text: str, size: float = 8.5, style: str = "") -> None:
        pdf.set_font("DejaVu", style, size)
        pdf.multi_cell(0, size * 0.5, text, new_x=XPos.LMARGIN, new_y=YPos.NEXT)

    m = content["model"]
    lo, hi = (t - CELSIUS_ZERO for t in m["validity_range_K"])
    unit = content["unit"]
    line(content["title"], 14, "B")
    line(f"Unit {unit.get('model', '')}, serial number {unit.get('serial_number', '')}; bench {content['bench']}; "
         f"issued {content['issue_date']}")  # fmt: skip
    line(f"Run {content['run']}; recording SHA-256 {content['recording_sha256']}; calibration digest "
         f"{content['calibration_sha256']}", 7)  # fmt: skip
    line("Model", 10.5, "B")
    line(f"{m['equation']}, T_ref = {m['reference_K'] - CELSIUS_ZERO:g} °C. Validity range: {lo:.2f} °C to "
         f"{hi:.2f} °C (the plateau temperatures' span); outside it {m['outside_range']}. Orders: "
         f"{m['order_selection']}. Fit χ² = {m['chi2']:.1f} for {m['dof']} degrees of freedom. "
         f"Uncertainties: {m['coverage']}.")  # fmt: skip
    plats = ", ".join(f"{p['temperature_K'] - CELSIUS_ZERO:.2f} °C ({p['direction'] or 'n/a'})"
                      for p in content["plateaus"])  # fmt: skip
    line(f"Plateaus (unit temperature, how reached): {plats}.")
    if content["skipped"]:
        line("Left out: " + "; ".join(content["skipped"]))
    line("Coefficients (display unit per °C^k), U(k = 2)", 10.5, "B")
    pdf.set_font("DejaVu", "", 7)
    for name, par in content["parameters"].items():
        si = kind_of(name)[2]
        terms = "; ".join(f"c{k} = {_fmt(c, si)} ± {_fmt(uu, si)}"
                          for k, (c, uu) in enumerate(zip(par["coefficients"], par["U_coefficients"], strict=True)))
        line(f"{name} [{par['display_unit']}] order {par['order']}: {terms}", 7)
    for group in _groups(list(content["parameters"])):
        pdf.add_page()
        kind = kind_of(group[0])[0]
        line(f"{kind}: against the unit's temperature", 10.5, "B")
        pdf.image(io.BytesIO(_plot(content, group)), w=pdf.epw)
        for name in group:
            par = content["parameters"][name]
            line(f"{name} [{par['display_unit']}]: T [°C] | value ± U(k=2) | residual after compensation", 7.5, "B")
            pdf.set_font("DejaVu", "", 6.5)
            with pdf.table(col_widths=(30, 60, 40), width=130, align="LEFT", line_height=3.2,
                           first_row_as_headings=False) as table:  # fmt: skip
                for row in parameter_rows(content, name):
                    r = table.row()
                    for c in row:
                        r.cell(c)
    return bytes(pdf.output())


def issue_thermal_certificate(
    tf: ThermalFile, pdf_path: str | Path, json_path: str | Path, issue_date: str | None = None
) -> dict[str, Any]:
    """Write the certificate's PDF and JSON (atomically); returns the content."""
    content = certificate_content(tf, issue_date)
    write_text_atomic(pdf_path, render_pdf(content))
    write_json(json_path, content)
    return content

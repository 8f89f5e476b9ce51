"""Render a :class:`benches.certificate.Certificate` to PDF bytes with fpdf2.

Fonts: DejaVu Sans from matplotlib's bundled fonts (``matplotlib/mpl-data/fonts/ttf``), embedded as subsets
(µ, σ, ″, ², ω, ∘ …); nothing is copied into the project. Determinism: the PDF creation date is the
certificate's ``creation_date`` (the recording's creation time), so equal certificates give equal bytes.
"""

from __future__ import annotations

import datetime as _dt
import importlib.util
import io
import math
from pathlib import Path
from typing import Any

from fpdf import FPDF, XPos, YPos

from analysis.identification.plan_legend import plan_legend_text

from .content import GYRO_MODEL_TEXT, MODEL_TEXT, Certificate, ambient_text

_FONT = "DejaVu"
_GREY = (235, 235, 235)
_DARK = (30, 45, 80)
_VERDICT_COLOURS = {
    "PASS": (30, 120, 50),
    "FAIL": (170, 25, 25),
    "INCOMPLETE": (190, 110, 0),
    "INCONCLUSIVE": (190, 110, 0),
    "NO LIMITS": (90, 90, 90),
}
_COMPONENT_SHORT = {
    "white_noise": "Noise",
    "bias_instability": "Flick.",
    "attitude": "Attit.",
    "local_g": "g",
    "model_mismatch": "Mism.",
    "azimuth": "Azim.",
    "latitude": "Lat.",
    "axis_orthogonality": "Orth.",
    "held_angles": "Held",
    "time_base": "Time",
}
"""Column heads of the budget table (each named in full under "Input quantities", with its key)."""
LAB_NAME = "tablebench calibration laboratory"


def _font_dir() -> Path:
    """matplotlib's bundled fonts, found without importing matplotlib (a quarter second, issue 32)."""
    spec = importlib.util.find_spec("matplotlib")
    assert spec is not None and spec.submodule_search_locations
    return Path(list(spec.submodule_search_locations)[0]) / "mpl-data" / "fonts" / "ttf"


class _CertificatePdf(FPDF):
    """A4 portrait with the certificate's header line and footer on every page."""

    def __init__(self, cert: Certificate) -> None:
        super().__init__(orientation="P", unit="mm", format="A4")
        self.cert = cert
        d = _font_dir()
        self.add_font(_FONT, "", str(d / "DejaVuSans.ttf"))
        self.add_font(_FONT, "B", str(d / "DejaVuSans-Bold.ttf"))
        self.add_font(_FONT, "I", str(d / "DejaVuSans-Oblique.ttf"))
        self.set_margins(15, 15, 15)
        self.set_auto_page_break(True, margin=18)
        self.alias_nb_pages()

    def header(self) -> None:
        if self.cert.bench.get("simulated"):
            # on EVERY page: a simulated bench calibrates no physical unit
            y = self.get_y()
            self.set_y(5)
            self.set_font(_FONT, "B", 8)
            self.set_text_color(160, 40, 0)
            self.cell(0, 4, "SIMULATED BENCH — NOT A CALIBRATION OF A PHYSICAL UNIT", align="C")
            self.set_text_color(0, 0, 0)
            self.set_y(max(y, 10))
        if self.page_no() == 1:
            return
        self.set_font(_FONT, "", 7.5)
        self.set_text_color(90, 90, 90)
        self.cell(0, 4, f"{self.cert.document.capitalize()} {self.cert.number} — issued {self.cert.issue_date}",
                  align="L")  # fmt: skip
        self.set_x(self.l_margin)
        self.cell(
            0, 4, f"Unit {self.cert.unit.get('serial_number', '')}", align="R", new_x=XPos.LMARGIN, new_y=YPos.NEXT
        )
        self.set_draw_color(*_DARK)
        self.line(self.l_margin, self.get_y() + 0.5, self.w - self.r_margin, self.get_y() + 0.5)
        self.ln(4)
        self.set_text_color(0, 0, 0)

    def footer(self) -> None:
        self.set_y(-13)
        self.set_font(_FONT, "", 7)
        self.set_text_color(90, 90, 90)
        sim = " · SIMULATED BENCH" if self.cert.bench.get("simulated") else ""
        self.cell(
            0,
            4,
            f"{self.cert.number}{sim} · Not to be reproduced except in full without the issuing laboratory's "
            "written approval.",
            align="L",
        )
        self.set_x(self.l_margin)
        self.cell(0, 4, f"Page {self.page_no()} of {{nb}}", align="R")
        self.set_text_color(0, 0, 0)

    # ---- building blocks ---------------------------------------------------------------------------------
    def section(self, title: str) -> None:
        if self.get_y() > self.h - 40:
            self.add_page()
        self.ln(2)
        self.set_font(_FONT, "B", 10.5)
        self.set_text_color(*_DARK)
        self.cell(0, 6, title, new_x=XPos.LMARGIN, new_y=YPos.NEXT)
        self.set_draw_color(*_DARK)
        self.line(self.l_margin, self.get_y(), self.w - self.r_margin, self.get_y())
        self.ln(1.5)
        self.set_text_color(0, 0, 0)
        self.set_font(_FONT, "", 8.5)

    def para(self, text: str, size: float = 8.5, style: str = "") -> None:
        """A paragraph across the text width, left-aligned, line height 0.48 × ``size`` mm.

        Broken into lines here, word by word from the font metrics, each line one ``cell``: fpdf's
        ``multi_cell`` re-measured the whole line for every character added (quadratic in the line length; the
        paragraphs were a third of the PDF's time, issue 32). A word wider than the line falls back to it.
        """
        self.set_font(_FONT, style, size)
        lines = self._wrap(text, self.epw - 2 * self.c_margin)
        if lines is None:
            self.multi_cell(0, size * 0.48, text, new_x=XPos.LMARGIN, new_y=YPos.NEXT)
            return
        h = size * 0.48
        for line in lines:
            if self.get_y() + h > self.page_break_trigger:
                self.add_page()
            y = self.get_y()
            self._line_text(self.l_margin, y, self.epw, h, line, "L")
            self.set_xy(self.l_margin, y + h)

    def _line_text(self, x: float, y: float, w: float, h: float, text: str, align: str) -> None:
        """One line of text in the box (x, y, w, h), placed as ``cell`` places it (``c_margin`` inside the box,
        the baseline 0.3 font sizes below its middle) but written directly with ``text``: a tenth of ``cell``'s
        cost, which went through fpdf's fragment and line machinery for every table cell (issue 32)."""
        if align == "L":
            tx = x + self.c_margin
        else:
            tw = self.get_string_width(text)
            tx = x + w - self.c_margin - tw if align == "R" else x + (w - tw) / 2
        self.text(tx, y + 0.5 * h + 0.3 * self.font_size, text)

    def _wrap(self, text: str, width: float) -> list[str] | None:
        """``text`` broken at spaces (and at its newlines) into lines of at most ``width`` mm in the current font;
        None if a single word is wider than that."""
        space = self.get_string_width(" ")
        out: list[str] = []
        for piece in text.split("\n"):
            line: list[str] = []
            used = 0.0
            for word in piece.split(" "):
                w = self.get_string_width(word) if word else 0.0
                if w > width:
                    return None
                if line and used + space + w > width:
                    out.append(" ".join(line).rstrip(" "))
                    line, used = [], 0.0
                    if not word:
                        continue  # a space at a break is dropped, as multi_cell does
                used = w if not line else used + space + w
                line.append(word)
            out.append(" ".join(line).rstrip(" "))
        return out

    def key_values(self, rows: list[tuple[str, str]], key_w: float = 45.0) -> None:
        """Two columns (the key bold) across the text width, rules between the rows; 8.5 pt, line height 4.4 mm,
        padding 0.8 mm × 1.2 mm (laid out as :meth:`grid`)."""
        self.set_draw_color(150, 150, 150)
        cols = [key_w, self.epw - key_w]
        for i, (k, v) in enumerate(rows):
            lines = [self._cell_lines(k, cols[0], "B", 8.5, 1.2), self._cell_lines(v, cols[1], "", 8.5, 1.2)]
            height = max(len(c) for c in lines) * 4.4 + 1.6
            if self.get_y() + height > self.page_break_trigger:
                self.add_page()
            elif i:
                self.line(self.l_margin, self.get_y(), self.l_margin + self.epw, self.get_y())
            self._grid_row(lines, cols, ["L", "L"], ["B", ""], 8.5, 4.4, 0.8, 1.2)
        self.set_font(_FONT, "", 8.5)

    def grid(
        self, head: list[str], rows: list[list[str]], widths: tuple[float, ...], align: tuple[str, ...], size: float
    ) -> None:
        """A table across the text width: a bold heading on grey (repeated on every page the table spans) with a
        rule under it, then the rows; columns of ``widths`` (scaled to the text width), cells aligned LEFT,
        RIGHT or CENTER, vertically centred, padding 0.6 mm × 1.0 mm, ``size`` pt, line height ``size`` / 2 mm.

        Laid out here, cell by cell with ``cell`` (one pass, widths from the font metrics): fpdf's table API
        line-broke every cell twice, character by character (most of the PDF's time, issue 32). A cell wider than
        its column wraps at spaces (:meth:`_wrap`).
        """
        scale = self.epw / sum(widths)
        cols = [w * scale for w in widths]
        aligns = [a[0].upper() for a in align]
        lh, pad_v, pad_h = size * 0.5, 0.6, 1.0
        self.set_draw_color(120, 120, 120)
        heading = [self._cell_lines(c, w, "B", size, pad_h) for c, w in zip(head, cols, strict=True)]
        self._grid_row(heading, cols, aligns, ["B"] * len(cols), size, lh, pad_v, pad_h, heading=True)
        for row in rows:
            lines = [self._cell_lines(c, w, "", size, pad_h) for c, w in zip(row, cols, strict=True)]
            height = max(len(c) for c in lines) * lh + 2 * pad_v
            if self.get_y() + height > self.page_break_trigger:
                self.add_page()
                self._grid_row(heading, cols, aligns, ["B"] * len(cols), size, lh, pad_v, pad_h, heading=True)
            self._grid_row(lines, cols, aligns, [""] * len(cols), size, lh, pad_v, pad_h)
        self.set_font(_FONT, "", size)

    def _cell_lines(self, text: str, width: float, style: str, size: float, pad: float) -> list[str]:
        """The lines of a table cell's text in a column ``width`` mm wide with ``pad`` mm each side."""
        self.set_font(_FONT, style, size)
        if "\n" not in text and self.get_string_width(text) <= width - 2 * pad:
            return [text]
        lines = self._wrap(text, width - 2 * pad)
        if lines is None:  # a word wider than the column: multi_cell breaks inside it
            return self.multi_cell(width, size * 0.5, text, padding=(0, pad), dry_run=True, output="LINES")
        return lines

    def _grid_row(self, lines: list[list[str]], cols: list[float], aligns: list[str], styles: list[str],
                  size: float, lh: float, pad_v: float, pad_h: float, heading: bool = False) -> None:  # fmt: skip
        """One table row at the current y (each cell's lines vertically centred; a heading on grey with a rule
        under it); y moves below it."""
        y = self.get_y()
        height = max(len(c) for c in lines) * lh + 2 * pad_v
        if heading:
            self.set_fill_color(*_GREY)
            self.rect(self.l_margin, y, self.epw, height, style="F")
        margin, self.c_margin = self.c_margin, pad_h
        x = self.l_margin
        for cell_lines, w, al, st in zip(lines, cols, aligns, styles, strict=True):
            self.set_font(_FONT, st, size)
            top = y + (height - len(cell_lines) * lh) / 2
            for j, text in enumerate(cell_lines):
                self._line_text(x, top + j * lh, w, lh, text, al)
            x += w
        self.c_margin = margin
        if heading:
            self.line(self.l_margin, y + height, self.l_margin + self.epw, y + height)
        self.set_xy(self.l_margin, y + height)

    def figure(self, fig: Any, width: float | None = None) -> None:
        """A figure centred: PNG bytes scaled to ``width`` (mm), or a vector drawing
        (:class:`benches.certificate.drawing.Drawing`) at its own size, on a new page if it does not fit."""
        if isinstance(fig, (bytes, bytearray)):
            w = width or self.epw
            self.image(io.BytesIO(fig), x=self.l_margin + (self.epw - w) / 2, w=w)
        else:
            if self.get_y() + fig.height > self.page_break_trigger:
                self.add_page()
            y = self.get_y()
            fig.draw(self, self.l_margin + (self.epw - fig.width) / 2, y, _FONT)
            self.set_y(y + fig.height)
        self.ln(2)


def _fmt_opt(v: object, spec: str, suffix: str = "") -> str:
    if v is None:
        return "—"
    if isinstance(v, str):
        return v
    return f"{format(float(v), spec)}{suffix}"  # type: ignore[arg-type]


def _title_block(pdf: _CertificatePdf, c: Certificate) -> None:
    """The title block, the issuer, and the simulated-bench and incomplete-run banners of page 1."""
    pdf.set_fill_color(*_DARK)
    pdf.rect(pdf.l_margin, 12, pdf.epw, 20, style="F")
    pdf.set_xy(pdf.l_margin + 4, 14)
    pdf.set_text_color(255, 255, 255)
    pdf.set_font(_FONT, "B", 17)
    pdf.cell(110, 8, c.document)
    pdf.set_font(_FONT, "", 8.5)
    pdf.set_xy(pdf.l_margin + 115, 14.5)
    pdf.multi_cell(
        pdf.epw - 119,
        4.2,
        f"{'Report' if c.is_noise_report else 'Certificate'} No. {c.number}\nIssue date {c.issue_date}\n"
        "Page 1 of {nb}"
        + (f"\nSupersedes No. {c.supersedes}" if getattr(c, "supersedes", "") else ""),
        align="R",
    )
    pdf.set_xy(pdf.l_margin + 4, 23)
    pdf.set_font(_FONT, "", 9)
    pdf.cell(110, 6, "Static record at one attitude — noise characterisation (no calibration)" if c.is_noise_report
             else f"{c.item_title} — three-axis turntable calibration")  # fmt: skip
    pdf.set_text_color(0, 0, 0)
    pdf.set_y(35)
    pdf.set_font(_FONT, "", 8)
    pdf.cell(0, 4, f"Issued by: {LAB_NAME}", new_x=XPos.LMARGIN, new_y=YPos.NEXT)
    if c.bench.get("simulated"):
        pdf.set_font(_FONT, "B", 8)
        pdf.set_text_color(120, 60, 0)
        pdf.cell(0, 4, "SIMULATED BENCH: the measurements come from the physics simulator, not a physical unit.",
                 new_x=XPos.LMARGIN, new_y=YPos.NEXT)  # fmt: skip
        pdf.set_text_color(0, 0, 0)
    pdf.ln(1.5)
    if not c.complete:
        pdf.set_fill_color(255, 236, 200)
        pdf.set_draw_color(190, 110, 0)
        pdf.set_line_width(0.6)
        pdf.set_font(_FONT, "B", 10)
        pdf.set_text_color(150, 70, 0)
        pdf.multi_cell(
            0,
            5.2,
            "INCOMPLETE RUN — issued with --allow-incomplete: "
            f"{c.incomplete_reason}. The results use only the completed steps and may not cover every "
            "parameter; this is not a full calibration.",
            border=1,
            fill=True,
            padding=2,
            align="L",
            new_x=XPos.LMARGIN,
            new_y=YPos.NEXT,
        )
        pdf.set_line_width(0.2)
        pdf.set_text_color(0, 0, 0)
        pdf.ln(2)


def _first_page(pdf: _CertificatePdf, c: Certificate) -> None:
    pdf.add_page()
    _title_block(pdf, c)
    # verdict box
    col = _VERDICT_COLOURS.get(c.verdict, (90, 90, 90))
    pdf.set_draw_color(*col)
    pdf.set_line_width(0.8)
    y0 = pdf.get_y()
    pdf.set_font(_FONT, "B", 14)
    pdf.set_text_color(*col)
    label = {
        "NO LIMITS": "NO CONFORMITY STATEMENT (no limits in the bench file)",
        "INCONCLUSIVE": "INCONCLUSIVE (conformity not established)",
        "INCOMPLETE": "INCOMPLETE RUN (no conformity statement)",
    }.get(c.verdict, c.verdict)
    pdf.cell(0, 9, f"  Result: {label}", border=1, new_x=XPos.LMARGIN, new_y=YPos.NEXT)
    pdf.set_line_width(0.2)
    pdf.set_text_color(0, 0, 0)
    if c.reasons:
        pdf.set_font(_FONT, "", 8.5)
        for r in c.reasons:
            pdf.multi_cell(0, 4.2, f"• {r}", new_x=XPos.LMARGIN, new_y=YPos.NEXT, align="L")
    elif c.verdict == "PASS":
        pdf.set_font(_FONT, "", 8.5)
        pdf.cell(0, 5, "Every parameter with a limit in the bench file is within it (decision rule: page 2).",
                 new_x=XPos.LMARGIN, new_y=YPos.NEXT)  # fmt: skip
    del y0
    pdf.ln(1)
    b, rec, proc = c.bench, c.recording, c.procedure
    temp = c.environment.get("unit_temperature_c") or {}
    temp_txt = (
        f"{temp['mean']:.2f} °C mean (min {temp['min']:.2f} °C, max {temp['max']:.2f} °C), unit's internal sensor"
        if temp
        else "not recorded"
    )
    info = c.identification.get("information") or {}
    noise = c.identification.get("measurement_noise") or {}
    lat = b.get("latitude_deg")
    site_txt = ", ".join(
        x
        for x in (
            str(b.get("site") or ""),
            _fmt_opt(lat, ".4f", "° latitude") if lat is not None else "",
            _fmt_opt(b.get("height_m"), ".1f", " m height") if b.get("height_m") is not None else "",
        )
        if x
    )
    unit_txt = _unit_text(c)
    rate_acc = b.get("rate_accuracy_ppm") or 0
    bench_txt = (
        f"{b.get('name', '')}: turntable {b.get('table_model', '')}, serial No. {b.get('table_serial_number', '')}; "
        f"attitude accuracy ±{b.get('attitude_accuracy_arcsec', 0):.2f}″"
        + (f", rate accuracy ±{rate_acc:.3g} ppm" if rate_acc else ", rate accuracy not stated")
    )
    g_txt = (
        f"{b['g']:.6f} m/s² — {b.get('g_source', '')}; standard uncertainty u(g) = {b.get('g_uncertainty', 0):.1e} m/s²"
    )
    rec_txt = (
        f"{rec.get('file')} ({rec.get('status')}, {rec.get('steps_complete')} of {rec.get('steps')} procedure "
        "steps completed, "
        f"{rec.get('samples')} samples at {rec.get('sample_rate_hz', 0):g} Hz, "
        f"{rec.get('duration_s', 0) / 60:.1f} min)\nSHA-256 {rec.get('sha256')}"
    )
    ident_txt = (
        f"{c.identification.get('method', '')} estimator over {len(c.identification.get('steps_used', []))} steps; "
        f"information rank {info.get('rank', '?')}, condition {_fmt_opt(info.get('condition'), '.3g')}; "
        f"noise {noise.get('source', '?')}"
    )
    sw_txt = f"tablebench {c.software_version} (certificate); recording by tablebench {rec.get('software_version', '')}"
    pdf.key_values(
        [
            ("Item calibrated", unit_txt),
            ("Calibration bench", bench_txt),
            ("Site", site_txt or "—"),
            ("Local gravity g", g_txt),
            ("Procedure", f"{proc.get('name', '')}; SHA-256 of its text: {proc.get('sha256', '')}" + _overrides(proc)),
            ("Date of calibration", _dates_text(rec)),
            ("Environment", f"Laboratory ambient: {ambient_text(c.environment.get('laboratory_ambient'))}; "
                            f"unit temperature {temp_txt}"),
            ("Recording", rec_txt),
            ("Identification", ident_txt),
            ("Software", sw_txt),
        ]
    )
    pdf.ln(2)
    pdf.para(
        "The expanded uncertainties reported are the combined standard uncertainties multiplied by the coverage "
        f"factor k = {c.coverage_factor:g}, which for a normal distribution corresponds to a coverage probability of "
        "approximately 95 %. The standard uncertainties were determined in accordance with the GUM (JCGM 100:2008). "
        "The results relate only to the item calibrated, at the conditions stated.",
        size=7.8,
    )
    _signature_block(pdf)


def _dates_text(rec: dict) -> str:
    """The dates of calibration, saying which clock is which: the start and end are the recording computer's
    wall clock (UTC); the recording's own duration is bench time, the unit's sample clock (a simulated bench
    runs faster than real time, so the two differ)."""
    start, end = rec.get("created_utc", ""), rec.get("updated_utc", "") or "—"
    dur = rec.get("duration_s")
    bench = f"; the recording spans {float(dur) / 60:.1f} min of bench time (the unit's sample clock)" if dur else ""
    return f"{start} to {end} (UTC, wall clock of the recording computer){bench}"


def _overrides(proc: dict) -> str:
    """The procedure parameters overridden for this run (``--set``), as shown on the certificate."""
    ov = proc.get("procedure_overrides") or {}
    if not ov:
        return "; parameters as in the procedure file (no overrides)"
    return "; parameters overridden for this run: " + ", ".join(f"{k} = {v:g}" for k, v in sorted(ov.items()))


def _signature_block(pdf: _CertificatePdf, first: str = "Calibrated by") -> None:
    if pdf.get_y() > pdf.h - 55:
        pdf.add_page()
    pdf.set_y(max(pdf.get_y() + 4, pdf.h - 52))
    pdf.set_font(_FONT, "B", 9)
    half = pdf.epw / 2
    y = pdf.get_y()
    for i, title in enumerate((first, "Approved by (authorised signatory)")):
        x = pdf.l_margin + i * half
        pdf.set_xy(x, y)
        pdf.set_font(_FONT, "B", 9)
        pdf.cell(half - 6, 5, title)
        pdf.set_font(_FONT, "", 8)
        for k, label in enumerate(("Name", "Signature", "Date")):
            yy = y + 12 + k * 9
            pdf.set_xy(x, yy - 4)
            pdf.cell(20, 4, label)
            pdf.set_draw_color(120, 120, 120)
            pdf.line(x + 20, yy, x + half - 8, yy)


def _results_page(pdf: _CertificatePdf, c: Certificate) -> None:
    pdf.add_page()
    pdf.section("Error model and sign conventions")
    pdf.para(f"Per sample, in the body frame:   {MODEL_TEXT}", style="B", size=9)
    if c.has_gyro:
        pdf.para(f"Gyro triad, body frame:   {GYRO_MODEL_TEXT}", style="B", size=9)
    pdf.ln(1)
    for line in c.conventions:
        pdf.para(f"• {line}", size=7.8)
    pdf.section("Results")
    rows = []
    for p in c.parameters:
        lim = "—" if p.display_limit is None else f"±{p.display_limit:.4g}"
        rows.append(
            [
                p.name,
                p.value_text,
                p.expanded_text,
                p.display_unit,
                lim,
                "yes" if p.identifiable else "NO",
                p.verdict,
            ]
        )
    pdf.grid(
        ["Parameter", "Value", f"U (k = {c.coverage_factor:g})", "Unit", "Limit", "Identified", "Result"],
        rows,
        (20, 28, 28, 18, 24, 20, 42),
        ("LEFT", "RIGHT", "RIGHT", "LEFT", "RIGHT", "CENTER", "LEFT"),
        8.2,
    )
    pdf.ln(1.5)
    pdf.para(
        "Decision rule (ILAC-G8:09/2019, non-binary statement with guard band w = U, k = 2): PASS when "
        "|value| + U ≤ limit; FAIL when |value| − U > limit; UNDECIDED when U straddles the limit (conditional "
        "pass or fail: the reason names the side) or U ≥ limit; NOT EVALUATED when this procedure cannot identify "
        "the parameter; INVALID for a non-finite value or uncertainty or a recording that failed its integrity "
        "check. The overall result is PASS only when every limited parameter passes; UNDECIDED or NOT EVALUATED "
        "make it INCONCLUSIVE, FAIL makes it FAIL, INVALID makes it INVALID. Uncertainty figures: the live "
        "display during the run shows the filter's white-noise ± (standard, k = 1); 'tablebench identify' and "
        "calibration.json give u, the identification's combined standard uncertainty (white noise ⊕ bias "
        "instability, k = 1); this certificate's U adds the type-B components of the budget (table, gravity, "
        "model mismatch) and is expanded, U = 2u. The pre-run plan ('tablebench plan', printed by 'run' and quoted "
        f"in the warnings) predicts 1σ figures; its {plan_legend_text()}. Values in SI and the full "
        "covariance are in the machine-readable certificate (JSON). µg = 9.80665e-6 m/s²; ppm = 1e-6; ″ = arcsecond.",
        size=7.6,
    )
    rel = c.identification.get("gyro_to_accelerometer_misalignment") or {}
    if rel:
        pairs = "; ".join(f"{k} {v['display_value']:.2f}″ ± {v['display_expanded']:.2f}″" for k, v in rel.items())
        pdf.para(
            "Gyro triad relative to the accelerometer triad (τ_g,ij − τ_ij; the table's orthogonality and the "
            f"mounting cancel): {pairs} (U, k = 2).",
            size=7.6,
        )


def _budget_page(pdf: _CertificatePdf, c: Certificate) -> None:
    pdf.add_page()
    pdf.section("Uncertainty budget (standard uncertainties u, k = 1, display units; U = 2u)")
    keys = [comp["key"] for comp in c.budget_components]
    head = ["Parameter", "Unit"] + [_COMPONENT_SHORT.get(k, k) for k in keys] + ["u", f"U (k={c.coverage_factor:g})"]
    rows = []
    for p in c.parameters:
        u_c = p.display_expanded / c.coverage_factor
        dec = max(1 - math.floor(math.log10(u_c)), 0) if u_c > 0 else 2  # u to two significant digits
        rows.append(
            [p.name, p.display_unit]
            + [f"{p.display_budget[k]:.{dec}f}" for k in keys]
            + [f"{u_c:.{dec}f}", p.expanded_text]
        )
    nk = len(keys)
    size = 7.8 if nk <= 7 else 6.6  # the whole unit's budget has a dozen columns: one line per cell
    rest = pdf.epw - 22 - 15 - 14 - 14
    pdf.grid(
        head,
        rows,
        (22, 15) + (rest / nk,) * nk + (14, 14),
        ("LEFT", "LEFT") + ("RIGHT",) * (nk + 2),
        size,
    )
    pdf.ln(1.5)
    pdf.set_font(_FONT, "B", 8.5)
    pdf.cell(0, 5, "Input quantities", new_x=XPos.LMARGIN, new_y=YPos.NEXT)
    for comp in c.budget_components:
        short = _COMPONENT_SHORT.get(comp["key"], comp["key"])
        pdf.para(f"• {short} — {comp['label']} (type {comp['type']}): {comp['source']}", size=7.8)
    pdf.ln(1)
    pdf.para(
        "Method (GUM law of propagation, linear estimator): the budget starts from the identification's own "
        "covariance — white noise (its posterior P) and the unit's bias instability as flicker correlated between "
        "the steps, exactly as identified — and adds the type-B components through the same 18-parameter model: "
        "an error e of the measurement equation z = f_out − f_ref moves the estimate by δx̂ = PΣHᵀR⁻¹e. Table "
        "attitude: a small navigation-frame tilt δφ per step, independent between steps, e = [f×]C_n^b δφ, "
        "u = bound/√3 (rectangular). Local g: e = f·δg/g, one δg for the run. Table rate (size effect): e = −2ε r̂∘c "
        "during spins about the axis with rate error ε, u(ε) = bound/√3. Model mismatch: per-step residual means "
        "scattering beyond what noise, flicker and attitude explain, propagated as per-step offsets. u is the root "
        "sum of squares of the components (they are uncorrelated by construction), U = 2u; the full combined "
        "covariance is in the JSON certificate.",
        size=7.6,
    )
    for n in c.budget_notes:
        pdf.para(f"Note: {n}", size=7.6, style="I")


def _unit_text(c: Certificate) -> str:
    """What the certificate calibrates: the whole unit, or its accelerometer triad only."""
    unit = f"{c.unit.get('model', '')}, serial No. {c.unit.get('serial_number', '')}"
    if any(p.name.startswith("gyro_") for p in c.parameters):
        return f"Accelerometer and gyro triads of {unit} (the whole unit: one recording, one reference, one time base)"
    return (
        f"Accelerometer triad of {unit} (only the accelerometer triad is calibrated by this certificate; the "
        "recording has no gyro data)"
    )


def _plots_pages(pdf: _CertificatePdf, c: Certificate) -> None:
    if "residuals" in c.plots:
        pdf.add_page()
        pdf.section("Residuals per step")
        pdf.figure(c.plots["residuals"], 175)
    if "gyro_residuals" in c.plots:
        pdf.add_page()
        pdf.section("Gyro residuals per step")
        pdf.figure(c.plots["gyro_residuals"], 175)
    if "coverage" in c.plots:
        pdf.section("Orientation coverage")
        pdf.figure(c.plots["coverage"], 165)
    if "convergence" in c.plots:
        pdf.add_page()
        pdf.section("Estimate convergence during the run")
        pdf.figure(c.plots["convergence"], 165)
    if "gyro_convergence" in c.plots:
        pdf.add_page()
        pdf.section("Gyro estimate convergence during the run")
        pdf.figure(c.plots["gyro_convergence"], 165)


def _analysis_section(pdf: _CertificatePdf, c: Certificate, title: str, kind: str, rows: list) -> None:
    """One analysis quoted on a certificate or noise report: its rows (channel, item, value) and its figures."""
    pdf.section(title)
    if rows:
        pdf.grid(["Channel", "Item", "Value"], [[r["channel"], r["item"], r["value"]] for r in rows],
                 (25, 35, pdf.epw - 60), ("LEFT", "LEFT", "LEFT"), 7.6)  # fmt: skip
    else:
        pdf.para("No results in the analysis file.")
    for name, png in c.analysis_plots:
        if name.startswith(f"{kind}/"):
            if pdf.get_y() > pdf.h - 110:
                pdf.add_page()
            pdf.figure(png, 150)


def _warnings_and_analyses(pdf: _CertificatePdf, c: Certificate) -> None:
    pdf.add_page()
    pdf.section("Warnings and limitations")
    if c.warnings:
        for w in c.warnings:
            pdf.para(f"• {w}", size=8)
    else:
        pdf.para("None.")
    titles = {"noise": "Noise analysis (Allan variance terms)", "periodic": "Periodic error", "drift": "Drift model"}
    for kind, rows in c.analyses.items():
        _analysis_section(pdf, c, titles.get(kind, kind), kind, rows)
    pdf.section("Traceability")
    b = c.bench
    rate_acc = b.get("rate_accuracy_ppm") or 0
    statement = (
        "Metrological traceability: the reference specific force is computed from the turntable's reported "
        f"attitude (stated accuracy ±{b.get('attitude_accuracy_arcsec', 0):.2f}″ per axis) and the local gravity "
        f"g = {b.get('g', 0):.6f} m/s² ({b.get('g_source', '')}, u(g) = {b.get('g_uncertainty', 0):.1e} m/s²); the "
        "angular-rate reference of every spin (the accelerometers' centripetal term and the gyro scale) from the "
        "turntable's encoder angle over the spin's time, which does not depend on how closely the table follows its "
        "commanded rate"
        + (f" (stated rate accuracy ±{rate_acc:.3g} ppm)" if rate_acc else "")
        + ". The attitude and gravity enter the uncertainty budget as type-B components."
    )
    stds = b.get("reference_standards") or []
    if b.get("simulated"):
        statement += (
            " SIMULATED BENCH: no physical reference standard is involved (the simulator realises these stated "
            "accuracies only when the bench sets realise_uncertainty_inputs), so this certificate is not traceable "
            "to SI."
        )
    elif stds:
        statement += " Reference standards (bench file):"
        for r in stds:
            overdue = " — CALIBRATION OVERDUE at the date of calibration" if r.get("overdue") else ""
            statement += (
                f"\n• {r['name']}, S/N {r.get('serial_number') or '—'}, certificate {r['certificate']}"
                f"{' by ' + r['calibrated_by'] if r.get('calibrated_by') else ''}, due {r['due']}{overdue}"
            )
    else:
        statement += (
            " The bench file lists no reference standards (reference_standards): traceability of the table "
            "and of g to SI is not documented by this certificate."
        )
    pdf.para(statement, size=7.8)
    pdf.para(
        f"Recording SHA-256: {c.recording.get('sha256')}\n"
        f"Calibration file SHA-256: {c.identification.get('calibration_sha256')}\n"
        f"Procedure text SHA-256: {c.procedure.get('sha256')}\n"
        "The JSON certificate next to this PDF carries the same content in SI units (values, uncertainties, "
        "budget, combined covariance) for production databases and firmware loading.",
        size=7.8,
    )


def render_pdf(cert: Certificate) -> bytes:
    """The certificate as PDF bytes (deterministic for a given certificate)."""
    pdf = _CertificatePdf(cert)
    created = _dt.datetime.fromisoformat(cert.creation_date)
    pdf.set_creation_date(created)
    pdf.set_title(f"Calibration certificate {cert.number}")
    pdf.set_author(LAB_NAME)
    pdf.set_subject(f"Accelerometer triad {cert.unit.get('model', '')} {cert.unit.get('serial_number', '')}")
    pdf.set_creator(f"tablebench {cert.software_version}")
    pdf.set_producer(f"tablebench {cert.software_version} (fpdf2)")
    if cert.is_noise_report:
        _noise_report_pages(pdf, cert)
        return bytes(pdf.output())
    _first_page(pdf, cert)
    _results_page(pdf, cert)
    _budget_page(pdf, cert)
    _plots_pages(pdf, cert)
    _warnings_and_analyses(pdf, cert)
    return bytes(pdf.output())


def _run_folder_analyses(pdf: _CertificatePdf, c: Certificate) -> None:
    """The analyses the user ran on the record (``RUN/noise``, ``periodic``, ``drift``), quoted in a noise report."""
    titles = {"noise": "Noise analysis of the run folder (tablebench noise)", "periodic": "Periodic error",
              "drift": "Drift model"}  # fmt: skip
    for key, rows in c.analyses.items():
        if not key.startswith("run folder "):
            continue
        kind = key.removeprefix("run folder ")
        _analysis_section(pdf, c, titles.get(kind, kind), kind, rows)


def _noise_report_pages(pdf: _CertificatePdf, c: Certificate) -> None:
    """The noise report of a static record (:mod:`benches.certificate.noise_report`): identity and conditions,
    the noise terms with U (k = 2), the record's statistics, the Allan deviation, warnings; no conformity."""
    pdf.add_page()
    _title_block(pdf, c)
    pdf.set_font(_FONT, "B", 12)
    pdf.set_text_color(*_VERDICT_COLOURS["NO LIMITS"])
    pdf.cell(0, 8, "  NOISE REPORT — no calibration, no conformity statement", border=1,
             new_x=XPos.LMARGIN, new_y=YPos.NEXT)  # fmt: skip
    pdf.set_text_color(0, 0, 0)
    pdf.para(
        "The recording is a static record: the unit held one attitude and the table did not rotate. That "
        "determines the unit's noise, reported here, but none of the error model's parameters (bias, scale factor, "
        "misalignment need several attitudes, the size effect needs spins); this document is therefore not a "
        "calibration certificate.",
        size=8.2,
    )
    pdf.ln(1)
    b, rec, n = c.bench, c.recording, c.noise
    temp = c.environment.get("unit_temperature_c") or {}
    temp_txt = f"{temp['mean']:.2f} °C mean (unit's internal sensor)" if temp else "not recorded"
    pdf.key_values(
        [
            ("Item measured", f"{c.unit.get('model', '')}, serial No. {c.unit.get('serial_number', '')}"),
            ("Bench", f"{b.get('name', '')}: turntable {b.get('table_model', '')}, serial No. "
                      f"{b.get('table_serial_number', '')} (held at rest)"),
            ("Site", str(b.get("site") or "—")),
            ("Procedure", f"{c.procedure.get('name', '')}; SHA-256 of its text: {c.procedure.get('sha256', '')}"
                          + _overrides(c.procedure)),
            ("Date of measurement", _dates_text(rec)),
            ("Environment", f"Laboratory ambient: {ambient_text(c.environment.get('laboratory_ambient'))}; "
                            f"unit temperature {temp_txt}"),
            ("Recording", f"{rec.get('file')} ({rec.get('status')}, {rec.get('samples')} samples at "
                          f"{rec.get('sample_rate_hz', 0):g} Hz)\nSHA-256 {rec.get('sha256')}"),
            ("Record analysed", f"step {n.get('step')!r}: {n.get('samples', 0)} samples, "
                                f"{float(n.get('duration_s') or 0) / 60:.1f} min of bench time"),
            ("Method", str(n.get("method", ""))),
            ("Software", f"tablebench {c.software_version}"),
        ]
    )  # fmt: skip
    pdf.section("Noise terms (expanded uncertainty U, k = 2)")
    rows = c.analyses.get("noise") or []
    if rows:
        pdf.grid(["Channel", "Term", "Value"], [[r["channel"], r["item"], r["value"]] for r in rows],
                 (25, 20, pdf.epw - 45), ("LEFT", "LEFT", "LEFT"), 7.6)  # fmt: skip
        pdf.para("Q quantisation, N white noise (velocity / angle random walk), B bias instability, K random walk, "
                 "R ramp (IEEE 952 / IEEE 1293 notation); a term whose U exceeds its value is not resolved by this "
                 "record.", size=7.4)  # fmt: skip
    else:
        pdf.para("No noise terms (see the warnings).")
    stats = c.analyses.get("record") or []
    if stats:
        pdf.section("Record statistics (for information)")
        pdf.grid(["Channel", "Item", "Value"], [[r["channel"], r["item"], r["value"]] for r in stats],
                 (25, 45, pdf.epw - 70), ("LEFT", "LEFT", "LEFT"), 7.6)  # fmt: skip
    if "noise" in c.plots:
        pdf.add_page()
        pdf.section("Overlapping Allan deviation of the record")
        pdf.figure(c.plots["noise"], 175)
    _run_folder_analyses(pdf, c)
    pdf.section("Warnings and limitations")
    for w in c.warnings or ["None."]:
        pdf.para(f"• {w}", size=8)
    _signature_block(pdf, "Measured by")


__all__ = ["render_pdf"]

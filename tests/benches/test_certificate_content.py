"""Issue 26, what a signing metrologist flagged on the certificate: each item checked on the rendered pages.

The PDF is rendered (pypdfium2 text of the pages, as a reader sees them), not the content model: the
laboratory's ambient conditions (and "not stated" listed under the warnings), the analyses' digits (value and
U to the same decimal) and display units (µg, °/h, not SI), the legend of the plan's σ columns, and a
convergence panel framed about its final value ± a few u. The NEES line of ``run``/``identify`` is checked
against the covariance the certificate states.
"""

from __future__ import annotations

import contextlib
import dataclasses
import io
import json
import re
from pathlib import Path

import numpy as np
import pypdfium2
import pytest

from analysis.units import MM
from benches.certificate import bench_info, build_certificate, format_with_uncertainty, issue_certificate
from benches.certificate.pdf import render_pdf
from benches.certificate.plots import convergence_figure
from benches.cli import main
from tests.certificate_fixtures import BENCH_TEXT, add_analyses, make_run_folder

DATE = "2026-11-27"


def _pages(pdf: bytes | Path) -> list[str]:
    doc = pypdfium2.PdfDocument(pdf if isinstance(pdf, bytes) else str(pdf))
    try:
        return [" ".join(doc[i].get_textpage().get_text_range().split()) for i in range(len(doc))]
    finally:
        doc.close()


def _warnings_section(pages: list[str]) -> str:
    text = " ".join(pages)
    start = text.index("Warnings and limitations")
    return text[start : start + 6000]


@pytest.fixture(scope="module")
def run_with_analyses(tmp_path_factory: pytest.TempPathFactory) -> Path:
    run = make_run_folder(tmp_path_factory.mktemp("content") / "run")
    add_analyses(run)
    return run


@pytest.fixture(scope="module")
def pages(run_with_analyses: Path) -> list[str]:
    pdf, _js, _v = issue_certificate(run_with_analyses, issue_date=DATE)
    return _pages(pdf)


def test_the_laboratory_ambient_conditions_are_on_page_one(pages):
    # benches/sim.yaml states site.ambient: 23.0 ± 1.0 °C, 45 % relative humidity
    assert "Laboratory ambient: 23.0 ± 1.0 °C air temperature, 45 % relative humidity" in pages[0], pages[0]
    assert "(site.ambient)" not in " ".join(pages)


def test_ambient_conditions_not_stated_say_so_and_are_a_limitation(run_with_analyses):
    bench = dataclasses.replace(bench_info(BENCH_TEXT, {}, {}), ambient={})
    cert = build_certificate(run_with_analyses, issue_date=DATE, bench=bench, with_plots=False)
    pages = _pages(render_pdf(cert))
    assert "Laboratory ambient: not stated in the bench file (site.ambient)" in pages[0]
    section = _warnings_section(pages)
    assert "None." not in section[:200]
    assert "ambient conditions are not stated in the bench file (site.ambient)" in section


def test_a_bench_file_without_ambient_gives_not_stated(tmp_path):
    text = BENCH_TEXT.replace(
        "  ambient: {temperature_c: 23.0, temperature_tolerance_c: 1.0, humidity_percent: 45}", "", 1
    )
    assert "ambient" not in text.split("turntable:")[0]
    info = bench_info(text, {}, {})
    assert info.ambient.get("temperature_k") is None


def test_analysis_rows_give_value_and_u_to_the_same_decimal(pages):
    text = " ".join(pages)
    # the fixture's noise.json: N = 14.99 µg/√Hz with σ = 0.015 → U = 0.030 (GUM: two significant digits)
    v, u = format_with_uncertainty(14.99, 2 * 0.015)
    assert f"{v} ± {u} µg/√Hz (U, k = 2)" in text
    rows = re.findall(r"(-?\d+(?:\.(\d+))?) ± (\d+(?:\.(\d+))?) (µg/√Hz|µg|Hz|deg/h|rad)", text)
    assert len(rows) >= 3, rows  # B and N of the noise file, the tone frequency
    for value, v_dec, unc, u_dec, unit in rows:
        assert len(v_dec) == len(u_dec), f"{value} ± {unc} {unit}: the value and U have different decimals"


def test_periodic_amplitudes_are_in_display_units_not_si(pages):
    text = " ".join(pages)
    start = text.index("Periodic error")
    periodic = text[start : text.index("Drift model", start)]
    # the fixture's tone: 2e-5 rad/s on gyro_z = 4.125 °/h; its residual RMS 3e-5 → 1e-5 rad/s
    assert "amplitude 4.125 deg/h" in periodic, periodic
    assert "6.188 → 2.063 deg/h" in periodic, periodic
    assert "rad/s" not in periodic


def test_the_plan_columns_have_a_legend_on_the_certificate(pages):
    text = " ".join(pages)
    for col in ("σ white = ", "σ total = ", "σ data = "):
        assert col in text, col


def test_convergence_panels_are_framed_about_the_final_value_within_a_few_u():
    """A trace that settles on 5 mm with u = 2 mm after a prior-dominated start: the panel spans final ± a few
    u (the ±2u band fills a good part of it), not a range in which the converged trace is a flat line."""
    k = 40
    t = np.arange(k) * 60.0
    u = np.full(k, 2.0 * MM)
    u[:5] = 40 * MM
    est = np.full(k, 5.0 * MM) + np.where(np.arange(k) < 5, -60 * MM, 0.0)
    est[20:] += np.linspace(0, 0.5 * MM, k - 20)
    names = ["r_x", "r_y", "r_z"]
    hist = {"time": t.tolist(), "estimate": np.tile(est[:, None], (1, 3)).tolist(),
            "sigma": np.tile(u[:, None], (1, 3)).tolist()}  # fmt: skip
    fig = convergence_figure(hist, names, ["size_effect"] * 3, np.full(3, est[-1]), [True, False, True])
    ax = [a for a in fig.panels if a.title.startswith("r_y")][0]
    lo, hi = ax.ylim
    final, u_mm = est[-1] / MM, 2.0
    assert lo < final - 2 * u_mm and hi > final + 2 * u_mm  # the ±2u band is inside the frame
    assert hi - lo <= 2 * 5 * u_mm  # final ± at most 5u: the band fills at least 40 % of the panel
    assert abs((lo + hi) / 2 - final) < 1e-9


def _run_cli(argv: list[str]) -> tuple[int, str]:
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main(argv)
    return code, out.getvalue() + err.getvalue()


@pytest.fixture(scope="module")
def simulated_run(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, str]:
    """A short ten-step run on the simulated bench (200 Hz), identified and certified by ``run`` itself."""
    from tests.simbench import bench_variant, short_ten_step

    tmp = tmp_path_factory.mktemp("sim-run")
    bench = bench_variant(tmp, rate=200.0)
    proc = tmp / "short.yaml"
    proc.write_text(short_ten_step(hold_s=4, warmup_s=5), encoding="utf-8")
    code, text = _run_cli(["run", "--bench", str(bench), "--procedure", str(proc), "--seed", "11", "--plain",
                           "--out", str(tmp / "run")])  # fmt: skip
    assert code in (0, 1), text[-2000:]
    return tmp / "run", text


def _nees_of_certificate(run: Path) -> tuple[float, int]:
    """NEES of the calibration against the simulator truth, with the covariance certificate.json states."""
    cert = json.loads((run / "certificate.json").read_text(encoding="utf-8"))
    cal = json.loads((run / "calibration.json").read_text(encoding="utf-8"))
    names = cert["parameter_names"]
    states = cal["truth"]["nees_states"]
    idx = [names.index(n) for n in states]
    e = np.array([cert["parameters"][n]["value"] - cal["truth"]["values"][n] for n in states])
    cov = np.array(cert["covariance"], dtype=float)[np.ix_(idx, idx)]
    return float(e @ np.linalg.solve(cov, e)), len(states)


def _printed_nees(text: str) -> tuple[float, int]:
    m = re.search(r"NEES ([0-9.]+) over (\d+) identified states against the simulator truth with the certificate's u",
                  text)  # fmt: skip
    assert m, f"no NEES line judged with the certificate's u: {text[-3000:]}"
    return float(m.group(1)), int(m.group(2))


def test_run_and_identify_print_the_nees_with_the_certificates_type_b_terms(simulated_run):
    run, text = simulated_run
    assert "static record" not in text and (run / "certificate.pdf").exists()  # a calibration, not a noise report
    expected, dof = _nees_of_certificate(run)
    got, n = _printed_nees(text)
    assert n == dof and got == pytest.approx(expected, abs=0.006), (got, expected)
    code, text = _run_cli(["identify", str(run), "--out", str(run.parent / "again.json")])
    assert code == 0, text[-2000:]
    got, n = _printed_nees(text)
    assert n == dof and got == pytest.approx(expected, abs=0.006), (got, expected)
    assert "with the identification's own u (type A) alone" in text


def test_the_whole_units_budget_table_has_one_line_per_parameter(simulated_run):
    """The whole unit's budget components (accelerometer and gyro, Earth rate, axis orthogonality, time base):
    every row of the rendered table is one line, its heads are short names, each explained under "Input
    quantities"."""
    run, _ = simulated_run
    cert = json.loads((run / "certificate.json").read_text(encoding="utf-8"))
    keys = [c["key"] for c in cert["uncertainty_budget"]["components"]]
    assert len(keys) >= 8 and "axis_orthogonality" in keys
    doc = pypdfium2.PdfDocument(str(run / "certificate.pdf"))
    try:
        page = next(t for t in (doc[i].get_textpage().get_text_range() for i in range(len(doc)))
                    if "Uncertainty budget" in t)  # fmt: skip
    finally:
        doc.close()
    lines = [ln.strip() for ln in page.splitlines()]
    number = r"-?\d+(?:\.\d+)?"
    for name, p in cert["parameters"].items():
        row = rf"{re.escape(name)} {re.escape(p['display_unit'])}(?: {number}){{{len(keys) + 2}}}"
        assert any(re.fullmatch(row, ln) for ln in lines), f"the budget row of {name} is not one line"
    assert "axis_orthogonality" not in page and "Input quantities" in page
    assert "Table axis orthogonality" in page  # the short head "Orth." named in full

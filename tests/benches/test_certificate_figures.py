"""The certificate's vector figures (benches/certificate/drawing.py, plots.py): projection and ticks against
independent references, determinism, and what a reader of the PDF finds on the figure pages."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pypdfium2
import pytest

from analysis.noise.terms import analyse_noise
from analysis.units import UG
from benches.certificate import issue_certificate
from benches.certificate.drawing import nice_ticks
from benches.certificate.plots import mollweide, plot_noise_report, plot_residuals
from tests.certificate_fixtures import make_run_folder


def test_mollweide_matches_matplotlibs_projection():
    from matplotlib.projections.geo import MollweideAxes

    rng = np.random.default_rng(4)
    lon = rng.uniform(-math.pi, math.pi, 400)
    lat = np.concatenate([rng.uniform(-math.pi / 2, math.pi / 2, 396), [math.pi / 2, -math.pi / 2, 1.5707, -1.5]])
    ref = MollweideAxes.MollweideTransform(resolution=1).transform(np.column_stack([lon, lat]))
    xy = mollweide(lon, lat)
    assert np.max(np.abs(xy - ref)) < 2e-3  # matplotlib stops its Newton iteration at 1e-3 rad
    # the defining equations, to full precision: y = √2 sin θ, 2θ + sin 2θ = π sin φ, x = 2√2/π λ cos θ
    th = np.arcsin(np.clip(xy[:, 1] / math.sqrt(2), -1, 1))
    assert np.max(np.abs(2 * th + np.sin(2 * th) - math.pi * np.sin(lat))) < 1e-9
    assert np.max(np.abs(xy[:, 0] - 2 * math.sqrt(2) / math.pi * lon * np.cos(th))) < 1e-9


@pytest.mark.parametrize("nbins", [4, 5, 7])
def test_ticks_are_nice_steps_inside_the_range_with_at_most_nbins_intervals(nbins):
    rng = np.random.default_rng(nbins)
    for _ in range(300):
        lo = rng.normal() * 10.0 ** rng.integers(-6, 6)
        hi = lo + max(abs(rng.normal()) * 10.0 ** rng.integers(-8, 6), 1e-5 * abs(lo), 1e-12)
        ticks, labels = nice_ticks(lo, hi, nbins)
        assert ticks.size >= 1 and len(labels) == ticks.size
        assert np.all(ticks >= lo - 1e-9 * abs(hi - lo)) and np.all(ticks <= hi + 1e-9 * abs(hi - lo))
        if ticks.size > 1:
            step = ticks[1] - ticks[0]
            mant = step / 10.0 ** math.floor(math.log10(step) + 1e-12)
            assert min(abs(mant - m) for m in (1, 2, 2.5, 5, 10)) < 1e-6, step
            assert step >= (hi - lo) / nbins * (1 - 1e-9)  # at most nbins intervals across the range
            # every label reads back as its tick's value exactly (enough decimals for the step), true minus sign
            back = np.array([float(s.replace("\u2212", "-")) for s in labels])
            assert np.all(np.abs(back - ticks) <= 1e-9 * np.maximum(np.abs(ticks), step)), (labels, ticks)
            assert not any("-" in s for s in labels)
            assert len(set(labels)) == len(labels)


def test_the_same_inputs_draw_the_same_figure():
    rows = [{"name": f"s{i}", "samples": 100 + i, "mean": [1e-5 * i, 0, -1e-5, 0, 0, 0],
             "rms": [4e-3, 4e-3, 4e-3, 1e-6, 1e-6, 1e-6]} for i in range(12)]  # fmt: skip
    a = plot_residuals(rows, np.full(3, 1.6e-5))
    b = plot_residuals([dict(r) for r in rows], np.full(3, 1.6e-5))
    assert bytes(a) == bytes(b) and len(bytes(a)) > 1000
    assert bytes(plot_residuals(rows[:-1], np.full(3, 1.6e-5))) != bytes(a)


@pytest.fixture(scope="module")
def pages(tmp_path_factory: pytest.TempPathFactory) -> list[str]:
    run = make_run_folder(tmp_path_factory.mktemp("fig") / "run")
    pdf, _, _ = issue_certificate(run, issue_date="2026-11-28")
    doc = pypdfium2.PdfDocument(str(Path(pdf)))
    try:
        return [" ".join(doc[i].get_textpage().get_text_range().split()) for i in range(len(doc))]
    finally:
        doc.close()


def test_figure_labels_are_text_on_their_pages(pages):
    """The figures are drawn, not pasted as images: their titles, axis labels and tick labels are text."""
    res = next(p for p in pages if "Residuals per step" in p)
    assert "mean residual, µg" in res and "RMS residual, µg" in res and "error bars: ±2σ of the mean" in res
    conv = next(p for p in pages if "Estimate convergence during the run" in p)
    assert "bench time, min" in conv and "b_x [µg]" in conv and "r_z [mm]" in conv
    cov = next(p for p in pages if "Orientation coverage:" in p)
    assert all(s in cov for s in ("+x up", "\u2212z up", "static holds", "45°"))


def test_noise_report_figure_panels_frame_the_deviation_in_display_units():
    """One log-log panel per channel framed about the OADEV in µg (the record is m/s²); same bytes twice."""
    x = np.random.default_rng(2).normal(0.0, 500 * UG, 20_000)
    res = analyse_noise({"accel_x": x}, 100.0, {"accel_x": "m/s^2"}, taus="octave", estimators=("oadev",),
                        fit_estimator="oadev")  # fmt: skip
    fig = plot_noise_report(res, title="t")
    (panel,) = fig.panels
    dev = np.asarray(res["channels"]["accel_x"]["deviations"]["oadev"]["value"], dtype=float) / UG
    lo, hi = panel.ylim
    assert lo < np.log10(np.nanmin(dev)) and np.log10(np.nanmax(dev)) < hi
    assert panel.title == "accel_x (accelerometer)"
    assert bytes(fig) == bytes(plot_noise_report(res, title="t"))

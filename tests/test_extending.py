"""The recipes of docs/extending.md, each done in test code only (no production file touched) and run through
the real seams: a toy unit frame format and a toy results store."""

from __future__ import annotations

import io
import re
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from benches.recording import open_recording
from benches.results.chain import register_copy_sink, unregister_copy_sink
from benches.results.sink import AnalysisDocument, CalibrationDocument, CertificateDocument, ResultSink
from benches.session import execute, identify_and_certify, prepare
from tests import REPO_ROOT
from tests.simbench import short_ten_step

SIM_TEXT = (REPO_ROOT / "benches" / "sim.yaml").read_text(encoding="utf-8")
ACL_BLOCK = re.compile(r"^  acl:.*?(?=^  axes:)", re.M | re.S)


def _short(tmp: Path) -> Path:
    p = tmp / "short.yaml"
    p.write_text(short_ten_step(hold_s=1, warmup_s=1), encoding="utf-8")
    return p


# ---- a unit format -----------------------------------------------------------------------------------------------

TOY_FRAME = """\
name: toy-unit
title: a toy unit, 31 bytes, big-endian floats, 8-bit sum
byte_order: big
sync: [0x7E, 0x42]
length: 31
fields:
  - {name: counter, offset: 2, type: uint16}
  - {name: ax, offset: 4, type: float32, channel: accel_x, unit: m/s^2}
  - {name: ay, offset: 8, type: float32, channel: accel_y, unit: m/s^2}
  - {name: az, offset: 12, type: float32, channel: accel_z, unit: m/s^2}
  - {name: gx, offset: 16, type: float32, channel: gyro_x, unit: rad/s}
  - {name: gy, offset: 20, type: float32, channel: gyro_y, unit: rad/s}
  - {name: gz, offset: 24, type: float32, channel: gyro_z, unit: rad/s}
  - {name: temp, offset: 28, type: int16, channel: temperature, scale: 0.01, unit: degC}
counter: {field: counter, modulus: 65536, step: 1}
checksum: {algorithm: sum8, offset: 30, covers: [0, 30]}
"""


def test_a_unit_format(tmp_path):
    (tmp_path / "toy-unit.yaml").write_text(TOY_FRAME, encoding="utf-8")
    text = SIM_TEXT.replace("  driver: sim\n  model: SIM-QA", "  driver: sim\n  frame: toy-unit.yaml\n  model: SIM-QA")
    bench = tmp_path / "bench.yaml"
    bench.write_text(text, encoding="utf-8")
    prep = prepare(bench, _short(tmp_path))
    assert prep.config.unit.frame == "toy-unit.yaml"
    result = execute(prep, tmp_path / "run", seed=2, transport="loopback", stream=io.StringIO(), live=False)
    assert result.status == "complete", result.reason
    with open_recording(tmp_path / "run") as rec:
        assert rec.n_samples == result.samples > 1000
        a = rec.samples(0, rec.n_samples, ("accel",)).accel
        assert a is not None and abs(np.median(np.linalg.norm(a, axis=1)) - 9.80) < 0.02  # gravity, over the toy wire
        assert any("toy-unit" in e.message for e in rec.events())


# ---- an auxiliary device (and a step kind that sets it): tests/benches/test_auxiliary_devices.py ----------------


# ---- a results store ---------------------------------------------------------------------------------------------


class ListSink:
    """A toy results store: keeps every document it is given."""

    name = "toy list"

    def __init__(self) -> None:
        self.kept: list[tuple[str, Any]] = []

    def calibration(self, doc: CalibrationDocument) -> CalibrationDocument:
        self.kept.append(("calibration", doc))
        return doc

    def certificate(self, doc: CertificateDocument) -> CertificateDocument:
        self.kept.append(("certificate", doc))
        return doc

    def analysis(self, doc: AnalysisDocument) -> AnalysisDocument:
        self.kept.append(("analysis", doc))
        return doc


def test_a_results_store(tmp_path):
    sink = ListSink()
    assert isinstance(sink, ResultSink)

    def factory(runs: Path, options: Mapping[str, Any]) -> ListSink:
        return sink

    register_copy_sink("toy-list", factory)
    try:
        prep = prepare(REPO_ROOT / "benches" / "sim.yaml", _short(tmp_path))
        folder = tmp_path / "run"
        folder.mkdir()
        result = execute(prep, folder, seed=2, transport="in-process", stream=io.StringIO(), live=False)
        assert result.status == "complete"
        identify_and_certify(folder, ["identification", "certificate"], say=lambda *a, **k: None, prep=prep)
    finally:
        unregister_copy_sink("toy-list")
    kinds = [k for k, _ in sink.kept]
    assert kinds == ["calibration", "certificate"]
    cal = sink.kept[0][1]
    assert cal.path == folder / "calibration.json" and cal.path.exists()  # the run folder (the record) came first
    cert = sink.kept[1][1]
    assert cert.pdf is not None and cert.pdf.exists() and cert.number.startswith("TB-")


def test_no_production_file_names_the_toys():
    """The recipes above touched no production file."""
    for pkg in ("core", "analysis", "procedures", "drivers", "benches"):
        for path in (REPO_ROOT / pkg).rglob("*.py"):
            text = path.read_text(encoding="utf-8")
            assert "toy-unit" not in text and "toy list" not in text, path

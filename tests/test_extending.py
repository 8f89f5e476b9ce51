"""The recipes of docs/extending.md, each done in test code only (no production file touched) and run through
the real seams: a toy turntable controller, a toy unit frame format, a toy auxiliary device (with a toy step
kind that sets it) and a toy results store."""

from __future__ import annotations

import io
import re
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from benches import devices
from benches.bench_config import load_bench, load_bench_text
from benches.factory import open_bench, open_table
from benches.recording import open_recording
from benches.results.chain import register_copy_sink, unregister_copy_sink
from benches.results.sink import AnalysisDocument, CalibrationDocument, CertificateDocument, ResultSink
from benches.session import execute, identify_and_certify, prepare
from drivers.connect import Connection
from drivers.protocols import TableState, Turntable
from drivers.sim.inprocess import SimTurntable
from drivers.sim.world import SimulatedWorld
from tests import REPO_ROOT
from tests.simbench import short_ten_step

SIM_TEXT = (REPO_ROOT / "benches" / "sim.yaml").read_text(encoding="utf-8")
ACL_BLOCK = re.compile(r"^  acl:.*?(?=^  axes:)", re.M | re.S)


def _short(tmp: Path) -> Path:
    p = tmp / "short.yaml"
    p.write_text(short_ten_step(hold_s=1, warmup_s=1), encoding="utf-8")
    return p


# ---- a controller ------------------------------------------------------------------------------------------------


class ToyTable:
    """A toy controller's driver: a thin wrapper that counts the commands it is given."""

    def __init__(self, inner: Turntable) -> None:
        self.inner, self.commands = inner, 0

    def limits(self):
        return self.inner.limits()

    def move_to(self, angles) -> None:
        self.commands += 1
        self.inner.move_to(angles)

    def spin(self, axis: int, rate: float) -> None:
        self.commands += 1
        self.inner.spin(axis, rate)

    def stop(self) -> None:
        self.inner.stop()

    def read_state(self) -> TableState:
        return self.inner.read_state()

    def heartbeat(self) -> None:
        self.inner.heartbeat()

    def clear_fault(self) -> None:
        self.inner.clear_fault()

    def close(self) -> None:
        self.inner.close()


@dataclass(frozen=True)
class ToySettings:
    speed: str


class ToyTwin:
    """The toy controller's simulated twin (in-process only)."""

    tables: list[ToyTable] = []

    def in_process(self, world: SimulatedWorld, timeout: float, alone: bool = False):
        t = ToyTable(SimTurntable(world))
        self.tables.append(t)
        return t, "toy controller (in-process)"


def _toy_settings(d, smap, p, *, link, simulated, limits) -> dict[str, Any]:
    speed = d.get("toy_speed", "normal")
    if speed not in ("normal", "fast"):
        raise smap.error(p + ("toy_speed",), f"{speed!r} is not allowed; choose normal or fast")
    return {"settings": ToySettings(speed)}


def _toy_connect(tt, timeout: float) -> Connection[Any]:
    world = SimulatedWorld.from_bench(load_bench(REPO_ROOT / "benches" / "sim.yaml"), 1)  # the "wire"
    conn: Any = Connection(ToyTable(SimTurntable(world)), world, [])
    conn.where = f"toy controller at {tt.address}"
    return conn


@pytest.fixture
def toy_controller():
    devices.register_controller(
        devices.ControllerKind(
            name="toy-table",
            title="a toy table (driver 'toy-table' or a simulated toy)",
            link_key="address",
            link_required="is required for driver 'toy-table' (e.g. 'toy://1')",
            settings_key=None,
            exclusive_keys=("toy_speed",),
            host_watchdog=False,
            no_watchdog="the toy protocol has no watchdog",
            parse_settings=_toy_settings,
            connect=_toy_connect,
            twins={"toy": lambda tt, min_wd: ToyTwin()},
        )
    )
    ToyTwin.tables = []
    yield
    devices.unregister_controller("toy-table")


def test_a_controller(toy_controller, tmp_path):
    text = ACL_BLOCK.sub("  toy_speed: fast\n", SIM_TEXT).replace("controller: acutrol", "controller: toy")
    bench = tmp_path / "toy.yaml"
    bench.write_text(text, encoding="utf-8")
    prep = prepare(bench, _short(tmp_path))
    assert prep.config.turntable.settings == ToySettings("fast")
    result = execute(prep, tmp_path / "run", seed=2, transport="in-process", stream=io.StringIO(), live=False)
    assert result.status == "complete", result.reason
    assert ToyTwin.tables and ToyTwin.tables[0].commands >= 20  # every move and spin went through the toy driver
    # a real bench names it by its driver name; the registry opens its link
    real = text.replace("  driver: sim\n  model", "  driver: toy-table\n  address: toy://7\n  model", 1)
    cfg = load_bench_text(real.split("\nunit:")[0] + "\nunit:" + real.split("\nunit:")[1].split("\nsimulation:")[0]
                          .replace("driver: sim", "driver: serial\n  address: /dev/null"), "real.yaml")  # fmt: skip
    with open_table(cfg) as b:
        assert isinstance(b.turntable, ToyTable) and "toy controller at toy://7" in b.describe()
    bad = real.replace("toy_speed: fast", "toy_speed: warp")
    with pytest.raises(Exception, match="toy_speed"):
        load_bench_text(bad, "bad.yaml")


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
            assert "toy-table" not in text and "toy-unit" not in text and "toy-oven" not in text, path


def test_open_bench_with_the_toy_controller(toy_controller):
    text = ACL_BLOCK.sub("", SIM_TEXT).replace("controller: acutrol", "controller: toy")
    cfg = load_bench_text(text, "toy.yaml")
    with open_bench(cfg, seed=1) as b:
        assert isinstance(b.turntable, ToyTable) and "toy controller" in b.describe()

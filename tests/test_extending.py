"""The recipes of docs/extending.md, each done in test code only (no production file touched) and run through
the real seams: a toy turntable controller, a toy unit frame format, a toy auxiliary device with a toy step kind
that sets it, and a toy results store."""

from __future__ import annotations

import dataclasses
import io
import math
import re
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar

import numpy as np
import pytest

from benches import devices, runner
from benches.bench_config import load_bench_text
from benches.factory import open_bench, open_table
from benches.recording import open_recording
from benches.results.chain import register_copy_sink, unregister_copy_sink
from benches.results.sink import AnalysisDocument, CalibrationDocument, CertificateDocument, ResultSink
from benches.session import Prepared, execute, identify_and_certify, prepare
from core.declare import Section, number
from core.yaml_source import ConfigError
from drivers.protocols import (
    AxisMode,
    FaultCode,
    LinkError,
    Readable,
    Reading,
    Settable,
    TableError,
    TableState,
    TableStatus,
    check_angles,
    check_spin,
)
from procedures.steps import Step
from tests import REPO_ROOT
from tests.simbench import short_ten_step

SIM_TEXT = (REPO_ROOT / "benches" / "sim.yaml").read_text(encoding="utf-8")
ACL_BLOCK = re.compile(r"^  acl:.*?(?=^  axes:)", re.M | re.S)


def _short(tmp: Path) -> Path:
    p = tmp / "short.yaml"
    p.write_text(short_ten_step(hold_s=1, warmup_s=1), encoding="utf-8")
    return p


# ---- a controller ------------------------------------------------------------------------------------------------
# A toy controller speaking a toy line protocol ("MOVE a b c", "RATE axis r", "STOP", "BEAT", "CLEAR", "STATE?",
# numbers as float.hex), its driver, its simulated twin on the one simulated world, its own bench settings (a
# declared section) and its registration: nothing else.


class ToyController:
    """The simulated toy controller: one command line in, one reply line out, on the simulated world."""

    def __init__(self, world: Any) -> None:
        self.world = world
        self.lines: list[str] = []

    def handle(self, line: str) -> str:
        self.lines.append(line)
        op, *args = line.split()
        w = self.world
        try:
            if op == "MOVE":
                w.command_position([float.fromhex(a) for a in args])
            elif op == "RATE":
                w.command_rate(int(args[0]), float.fromhex(args[1]))
            elif op in ("STOP", "BEAT", "CLEAR"):
                {"STOP": w.command_stop, "BEAT": w.heartbeat, "CLEAR": w.clear_fault}[op]()
            elif op == "STATE?":
                st = w.table_state()
                nums = " ".join(float(x).hex() for x in (st.time, *st.angles, *st.rates))
                return f"{nums} {int(st.status)} {int(st.fault_code)} {' '.join(str(int(m)) for m in st.modes)}"
            else:
                return f"ERR unknown command {op}"
        except TableError as exc:
            return f"ERR {exc}"
        return "OK"


class ToyTable:
    """The toy controller's driver (:class:`drivers.protocols.Turntable`): every command checked against the
    limits before anything is sent, on an open line transport ``send(line) -> reply``."""

    def __init__(self, send: Callable[[str], str], limits: Any, settings: ToySettings) -> None:
        self.send, self._limits, self.settings = send, tuple(limits), settings
        self.closed = False

    def _do(self, line: str) -> str:
        if self.closed:
            raise LinkError("toy table: driver closed")
        reply = self.send(line)
        if reply.startswith("ERR"):
            raise TableError(f"toy table refused {line.split()[0]}: {reply[4:]}")
        return reply

    def limits(self):
        return self._limits

    def move_to(self, angles) -> None:
        self._do("MOVE " + " ".join(float(a).hex() for a in check_angles(angles, self._limits)))  # type: ignore[arg-type]

    def spin(self, axis: int, rate: float) -> None:
        ax, r = check_spin(axis, rate, self._limits)  # type: ignore[arg-type]
        self._do(f"RATE {ax} {r.hex()}")

    def stop(self) -> None:
        self._do("STOP")

    def heartbeat(self) -> None:
        self._do("BEAT")

    def clear_fault(self) -> None:
        self._do("CLEAR")

    def read_state(self) -> TableState:
        f = self._do("STATE?").split()
        nums = [float.fromhex(x) for x in f[:7]]
        return TableState(
            time=nums[0],
            angles=np.array(nums[1:4]),
            rates=np.array(nums[4:7]),
            status=TableStatus(int(f[7])),
            fault_code=FaultCode(int(f[8])),
            modes=tuple(AxisMode(int(m)) for m in f[9:12]),  # type: ignore[arg-type]
        )

    def close(self) -> None:
        self.closed = True


@dataclass(frozen=True)
class ToySettings:
    """The toy controller's own bench settings (``turntable.toy``)."""

    echo_ms: float


TOY_SECTION = Section(number("echo_ms", 0.0, minimum=0, maximum=1000))


def _toy_settings(d, smap, p, *, link, simulated) -> dict[str, Any]:
    return {"settings": TOY_SECTION.build(ToySettings, d.get("toy"), smap, p + ("toy",))}


@dataclass
class ToyTwin:
    """The toy controller's simulated twin (in-process only: it has no server)."""

    settings: ToySettings
    controllers: list[ToyController]
    in_process_only: str = "the toy table is simulated in-process only: use --transport in-process"
    unit_note: bool = True

    def in_process(self, world, timeout, alone=False):
        ctl = ToyController(world)
        self.controllers.append(ctl)
        return ToyTable(ctl.handle, world.table_limits(), self.settings), "toy table (in-memory)"

    def serve(self, world):
        raise ValueError(self.in_process_only)

    def connect(self, server, timeout, clock, alone=False):
        raise ValueError(self.in_process_only)

    def describe(self, server) -> str:
        return "toy"

    def describe_alone(self, server) -> str:
        return "toy"


def _toy_connect(tt, timeout):
    raise LinkError(f"turntable: no toy table answers at {tt.address}; check its power")


@pytest.fixture
def toy_controller():
    made: list[ToyController] = []
    devices.register_controller(
        devices.ControllerKind(
            name="toy-table",
            link_key="address",
            link_required="is required for driver 'toy-table' (e.g. 'toy://bench-1')",
            own_keys={"toy": "is only for the toy table"},
            no_watchdog="the toy line protocol",
            parse_settings=_toy_settings,
            connect=_toy_connect,
            twins={"toy": lambda tt, min_watchdog: ToyTwin(tt.settings, made)},
        )
    )
    yield made
    devices.unregister_controller("toy-table")


def _toy_bench(text: str = SIM_TEXT, extra: str = "    echo_ms: 5\n") -> str:
    text = ACL_BLOCK.sub("  toy:\n" + extra, text)
    return text.replace("  controller: acutrol ", "  controller: toy ")


def test_a_controller_is_a_registration(toy_controller, tmp_path):
    cfg = load_bench_text(_toy_bench(), tmp_path / "toy.yaml")
    assert cfg.turntable.sim_controller == "toy" and cfg.turntable.settings == ToySettings(echo_ms=5.0)
    assert cfg.turntable.acl is None and cfg.turntable.watchdog is None
    with pytest.raises(ConfigError, match=r"toy.yaml:\d+: turntable.toy.echo_ms: .*1000"):
        load_bench_text(_toy_bench(extra="    echo_ms: 5000\n"), tmp_path / "toy.yaml")
    with pytest.raises(ConfigError, match=r"turntable.acl: is only for an ACUTROL table"):
        load_bench_text(SIM_TEXT.replace("  controller: acutrol ", "  controller: toy "), tmp_path / "toy.yaml")
    real = _toy_bench().replace("  driver: sim\n  model: SIM-3AX", "  driver: toy-table\n  model: SIM-3AX")
    real = (
        real[: real.index("\nsimulation:")].replace(
            "  driver: sim\n  model: SIM-QA", "  driver: serial\n  address: /dev/null\n  model: SIM-QA"
        )
        + "\n"
    )
    with pytest.raises(ConfigError, match=r"turntable.address: is required for driver 'toy-table'"):
        load_bench_text(real, tmp_path / "real.yaml")
    real_cfg = load_bench_text(real.replace("  driver: toy-table\n", "  driver: toy-table\n  address: toy://b1\n"),
                               tmp_path / "real.yaml")  # fmt: skip
    with pytest.raises(LinkError, match="no toy table answers at toy://b1"):
        open_table(real_cfg)  # the factory reached the registered connect function
    with pytest.raises(ConfigError, match="in-process only"):
        open_table(cfg, transport="loopback")


def test_a_controller_runs_a_procedure(toy_controller, tmp_path):
    bench = tmp_path / "toy.yaml"
    bench.write_text(_toy_bench(), encoding="utf-8")
    prep = prepare(bench, _short(tmp_path))  # what `tablebench check` does: compile against the toy's limits
    with open_table(prep.config) as b:
        assert "toy table (in-memory)" in b.describe()
        b.turntable.move_to([0.0, 0.5, 0.0])
        b.world.produce(4000)
        assert abs(b.turntable.read_state().angles[1] - 0.5) < 1e-4
    result = execute(prep, tmp_path / "run", seed=2, transport="in-process", stream=io.StringIO(), live=False)
    assert result.status == "complete", result.reason
    ctl = toy_controller[-1]
    assert any(x.startswith("MOVE") for x in ctl.lines) and any(x.startswith("RATE") for x in ctl.lines)
    with open_recording(tmp_path / "run") as rec:
        table = rec.table()
        n_spins = sum(s.kind == "spin" for s in prep.compiled.steps)
        assert n_spins == 3 and sum(s.kind == "spin" for s in rec.steps) == n_spins
        assert len(rec.steps) == len(prep.compiled.steps) and all(s.status == "complete" for s in rec.steps)
        assert np.max(np.abs(table.rates)) > math.radians(29)  # the toy table spun at the procedure's 30 °/s


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


# ---- an auxiliary device, and a step kind that sets it ---------------------------------------------------------


@dataclass(frozen=True)
class OvenSettings:
    """The toy oven's bench section (``oven:``), SI."""

    start: float
    lag: float


OVEN_SECTION = Section(
    number("start_k", 293.15, minimum=200, maximum=500, attr="start"),
    number("lag_s", 2.0, minimum=0, exclusive_minimum=True, attr="lag"),
)


class ToyOven:
    """A settable toy oven on the simulated world: its air follows the set point with a first-order lag in bench
    time (the world's clock), so settling is counted in samples, never slept."""

    def __init__(self, world: Any, settings: OvenSettings) -> None:
        self.world, self.s = world, settings
        self.setpoint = self.air = settings.start
        self._t = 0.0
        self.closed = False

    def _advance(self) -> None:
        t = float(self.world.time)
        dt, self._t = t - self._t, t
        self.air += (self.setpoint - self.air) * (1.0 - math.exp(-dt / self.s.lag))

    def read(self) -> Reading:
        self._advance()
        return Reading({"air": self.air, "setpoint": self.setpoint}, {"air": "K", "setpoint": "K"})

    def set(self, setpoint: float) -> None:
        self.setpoint = float(setpoint)

    def settled(self) -> bool:
        self._advance()
        return abs(self.air - self.setpoint) < 0.05

    def status(self) -> str:
        return f"air {self.air:.2f} K"

    def close(self) -> None:
        self.closed = True


def _parse_oven(data, smap, path) -> OvenSettings:
    return OVEN_SECTION.build(OvenSettings, data, smap, path)


@dataclass(frozen=True, kw_only=True)
class SetOven(Step):
    """A toy step kind: set the oven and acquire (recorded, not counted) until it settles."""

    kind: ClassVar[str] = "set-oven"
    setpoint: float = 0.0


def _run_set_oven(r: runner.Runner, step: Step) -> None:
    assert isinstance(step, SetOven)
    r.set_device(step, "oven", step.setpoint, timeout_s=60.0)


@pytest.fixture
def toy_oven():
    opened: list[ToyOven] = []

    def open_oven(settings, world, timeout):
        dev = ToyOven(world, settings)
        opened.append(dev)
        return dev, [dev.close], "oven: toy (simulated)"

    devices.register_auxiliary(devices.AuxiliaryKind(key="oven", parse=_parse_oven, open=open_oven, record_every=0.5))
    runner.register_step(SetOven, _run_set_oven)
    yield opened
    devices.unregister_auxiliary("oven")
    runner.unregister_step(SetOven)


def test_an_auxiliary_device_is_recorded_and_set_by_a_step_kind(toy_oven, tmp_path):
    text = SIM_TEXT.rstrip("\n") + "\noven:\n  start_k: 293.15\n  lag_s: 2\n"
    cfg = load_bench_text(text, tmp_path / "b.yaml")
    assert cfg.auxiliary == {"oven": OvenSettings(start=293.15, lag=2.0)}
    with pytest.raises(ConfigError, match=r"b.yaml:\d+: oven.lag_s: "):
        load_bench_text(text.replace("lag_s: 2", "lag_s: -1"), tmp_path / "b.yaml")
    (tmp_path / "b.yaml").write_text(text, encoding="utf-8")
    prep = prepare(tmp_path / "b.yaml", _short(tmp_path))
    steps = list(prep.compiled.steps)
    steps.insert(1, SetOven(index=1, name="oven/set", setpoint=303.15))
    steps = [dataclasses.replace(s, index=i) for i, s in enumerate(steps)]
    starts = list(prep.compiled.start_angles)
    starts.insert(1, starts[1])
    compiled = dataclasses.replace(prep.compiled, steps=tuple(steps), start_angles=tuple(starts))
    prep = Prepared(prep.bench_path, prep.procedure_path, prep.config, compiled, prep.estimated_s, {})
    result = execute(prep, tmp_path / "run", seed=3, transport="in-process", stream=io.StringIO(), live=False)
    assert result.status == "complete", result.reason
    (oven,) = toy_oven
    assert oven.closed and isinstance(oven, Settable) and isinstance(oven, Readable)
    with open_recording(tmp_path / "run") as rec:
        assert rec.aux_names() == ["oven"]
        aux = rec.aux("oven")
        assert aux.units == {"air": "K", "setpoint": "K"} and len(aux) > 10
        assert aux.channels["setpoint"][0] == pytest.approx(293.15) and aux.channels["setpoint"][-1] == 303.15
        step = rec.step("oven/set")
        assert step.status == "complete" and step.end_sample > step.start_sample
        t_end = step.end_sample / rec.header.sample_rate_hz
        after = aux.time >= t_end + 0.5
        assert np.all(np.abs(aux.channels["air"][after] - 303.15) < 0.05)  # the step waited until it settled
        assert np.all(np.diff(aux.time) >= 0.5 - 1e-9)  # one reading per 0.5 s of bench time
        assert any("oven: set point 303.15" in e.message for e in rec.events())
    with open_bench(cfg, seed=1) as b:
        assert "oven: toy (simulated)" in b.describe() and b.aux_every == {"oven": 0.5}
        assert isinstance(b.aux["oven"], ToyOven)


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
            for toy in ("toy-unit", "toy list", "toy-table", "ToyOven", "set-oven", "ToyController"):
                assert toy not in text, path

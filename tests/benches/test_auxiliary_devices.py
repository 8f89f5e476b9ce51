"""Auxiliary devices by name: a bench names a registered device, the factory opens its simulated twin on the
world, the runner records its readings under /aux/<name>, and a step (a kind taught to the runner) sets it."""

from __future__ import annotations

import dataclasses
import io
from dataclasses import dataclass
from typing import Any, ClassVar

import pytest

from benches import devices, runner
from benches.bench_config import load_bench_text
from benches.recording import open_recording
from benches.session import Prepared, execute
from core.yaml_source import ConfigError, get_number
from drivers.protocols import Readable, Reading, Settable
from procedures.compiler import compile_procedure
from procedures.loader import load_procedure_text
from procedures.steps import Step
from tests import REPO_ROOT
from tests.simbench import short_ten_step

SIM_TEXT = (REPO_ROOT / "benches" / "sim.yaml").read_text(encoding="utf-8")


@dataclass(frozen=True)
class OvenSettings:
    start_k: float
    lag_s: float


class ToyOven:
    """A settable 'oven' on the simulated world: its air approaches the set point with a first-order lag in
    bench time (the world's clock), so settling is counted in samples, never slept."""

    def __init__(self, world: Any, settings: OvenSettings) -> None:
        self.world, self.s = world, settings
        self.setpoint = self.air = settings.start_k
        self._t = 0.0
        self.closed = False

    def _advance(self) -> None:
        t = float(self.world.time)
        dt, self._t = t - self._t, t
        self.air += (self.setpoint - self.air) * min(1.0, dt / self.s.lag_s)

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


def _parse(d, smap, p) -> OvenSettings:
    return OvenSettings(
        start_k=get_number(d, smap, p, "start_k", 293.15, minimum=0, exclusive_minimum=True),
        lag_s=get_number(d, smap, p, "lag_s", 2.0, minimum=0, exclusive_minimum=True),
    )


@dataclass(frozen=True, kw_only=True)
class SetOven(Step):
    """A toy step kind: set the oven and wait until it settles (samples recorded, not counted)."""

    kind: ClassVar[str] = "set-oven"
    setpoint: float = 0.0


def _run_set_oven(r: runner.Runner, step: Step) -> None:
    assert isinstance(step, SetOven)
    r.set_device(step, "oven", step.setpoint, timeout_s=60.0)


@pytest.fixture
def oven_kind():
    opened: list[ToyOven] = []

    def twin(world, settings):
        dev = ToyOven(world, settings)
        opened.append(dev)
        return dev, [dev.close]

    devices.register_auxiliary(devices.AuxiliaryKind(name="toy-oven", parse=_parse, twin=twin, title="toy oven"))
    runner.register_step(SetOven, _run_set_oven)
    yield opened
    devices.unregister_auxiliary("toy-oven")
    runner.STEP_EXECUTORS.pop(SetOven, None)


def _bench(extra: str) -> str:
    return SIM_TEXT.rstrip("\n") + "\n" + extra


def test_a_bench_names_a_registered_device_and_its_settings_are_parsed(oven_kind):
    cfg = load_bench_text(_bench("auxiliary:\n  oven:\n    driver: toy-oven\n    lag_s: 3\n"), "b.yaml")
    (spec,) = cfg.auxiliary
    assert (spec.name, spec.driver, spec.settings) == ("oven", "toy-oven", OvenSettings(293.15, 3.0))


@pytest.mark.parametrize(
    ("extra", "where", "says"),
    [
        ("auxiliary:\n  oven:\n    driver: no-such\n", "b.yaml:", "toy-oven"),
        ("auxiliary:\n  oven:\n    driver: toy-oven\n    lag_s: -1\n", "b.yaml:", "lag_s"),
        ("auxiliary:\n  9oven:\n    driver: toy-oven\n", "b.yaml:", "device name"),
    ],
)
def test_bad_auxiliary_sections_name_the_line_and_the_fix(oven_kind, extra, where, says):
    with pytest.raises(ConfigError) as e:
        load_bench_text(_bench(extra), "b.yaml")
    assert where in str(e.value) and says in str(e.value)


def test_a_run_records_the_device_and_a_step_sets_it(oven_kind, tmp_path):
    cfg = load_bench_text(_bench("auxiliary:\n  oven:\n    driver: toy-oven\n    lag_s: 2\n"), "b.yaml")
    proc = load_procedure_text(short_ten_step(hold_s=1, warmup_s=2), "p.yaml")
    compiled = compile_procedure(proc, limits=cfg.turntable.limits, mounting=cfg.unit.mounting)
    steps = list(compiled.steps)
    steps.insert(1, SetOven(index=1, name="oven/set", setpoint=303.15))
    steps = [dataclasses.replace(s, index=i) for i, s in enumerate(steps)]
    starts = list(compiled.start_angles)
    starts.insert(1, starts[1])
    compiled = dataclasses.replace(compiled, steps=tuple(steps), start_angles=tuple(starts))
    prep = Prepared(cfg.path, cfg.path, cfg, compiled, compiled.estimated_duration(cfg.turntable.limits), {})
    result = execute(prep, tmp_path, seed=3, transport="in-process", stream=io.StringIO(), live=False)
    assert result.status == "complete", result.reason
    (oven,) = oven_kind
    assert oven.closed and isinstance(oven, Settable) and isinstance(oven, Readable)
    with open_recording(tmp_path / "recording.h5") as rec:
        assert rec.aux_names() == ["oven"]
        aux = rec.aux("oven")
        assert aux.units == {"air": "K", "setpoint": "K"} and len(aux) > 10
        assert aux.time[0] <= 1.0 and (aux.time[-1] - aux.time[0]) > 0.8 * result.bench_seconds
        assert aux.channels["setpoint"][0] == pytest.approx(293.15) and aux.channels["setpoint"][-1] == 303.15
        assert abs(aux.channels["air"][-1] - 303.15) < 0.05  # the step waited until it settled
        step = rec.step("oven/set")
        assert step.status == "complete" and step.end_sample > step.start_sample
        assert any("oven: set point 303.15" in e.message for e in rec.events())

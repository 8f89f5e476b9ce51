"""A bench with an Ideal Aerosmith single-axis table: the shipped simulated example loads, check/plan/run refuse a
procedure that needs the gimbals the table does not have and accept one that does not, the table command works
on the one axis, and the bench-file mistakes are one line with file and line."""

from __future__ import annotations

import io
import math
import subprocess
import sys

import pytest

from benches import factory
from benches.bench_config import load_bench
from benches.cli.commands import table as cmd
from benches.session import prepare
from core.errors import UserError
from core.yaml_source import ConfigError
from tests import REPO_ROOT

BENCH = REPO_ROOT / "benches" / "sim-ideal-aerosmith.yaml"


def test_the_example_bench_loads_with_two_absent_gimbals():
    tt = load_bench(BENCH).turntable
    assert tt.limits[0].absent and tt.limits[1].absent and not tt.limits[2].absent
    assert tt.aerosmith is not None and tt.aerosmith.axis == "inner" and tt.watchdog is None


def test_check_refuses_a_procedure_needing_absent_gimbals_and_accepts_one_that_does_not():
    with pytest.raises(UserError, match="outer gimbal would go to .*absent \\(the table has no such axis\\)"):
        prepare(BENCH, "ten-step")
    prepare(BENCH, "static-noise", {"duration_s": 60.0})
    r = subprocess.run(
        [sys.executable, "-m", "benches.cli", "plan", "--procedure", "ten-step", "--bench", str(BENCH)],
        cwd=REPO_ROOT,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert r.returncode == 2 and "has no such axis" in r.stderr and len(r.stderr.strip().splitlines()) == 1


def test_table_command_on_the_one_axis():
    bench = factory.open_table(load_bench(BENCH), seed=1, transport="in-process")
    try:
        out = io.StringIO()
        assert cmd.execute(bench, "spin", (2, math.radians(20)), out=out) == 0
        assert "the inner axis is turning at 20 °/s" in out.getvalue()
        assert cmd.execute(bench, "stop", (), out=out) == 0
        assert cmd.execute(bench, "move", ((0.0, 0.0, 0.0),), out=out) == 0 and "IN_POSITION" in out.getvalue()
    finally:
        bench.close()
    with pytest.raises(UserError, match="has no outer axis"):
        cmd.parse_demand("spin", ["outer", "5"], load_bench(BENCH).turntable.limits)


@pytest.mark.parametrize(
    "old,new,words",
    [
        ("    outer: absent\n", "    outer: {rate_max_dps: 100.0, accel_max_dps2: 10.0}\n", "has one axis (inner"),
        ("  axes:\n", "  watchdog_s: 2.0\n  axes:\n", "no host heartbeat or watchdog"),
        ("    axis: inner ", "    axis: sideways ", "outer, middle, inner"),
    ],
)
def test_bench_mistakes_are_one_line(tmp_path, old, new, words):
    text = BENCH.read_text(encoding="utf-8")
    assert old in text
    f = tmp_path / "b.yaml"
    f.write_text(text.replace(old, new, 1), encoding="utf-8")
    with pytest.raises(ConfigError) as e:
        load_bench(f)
    assert words in str(e.value) and f"{f}:" in str(e.value) and "\n" not in str(e.value)

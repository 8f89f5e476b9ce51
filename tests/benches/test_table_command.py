"""``tablebench table`` against the simulated ACUTROL: jog commands, limits, faults, lost link, signals."""

from __future__ import annotations

import argparse
import io
import math
import os
import signal
import subprocess
import sys

import pytest

from benches import factory
from benches.cli.commands import table as cmd
from tests import REPO_ROOT
from tests.simbench import bench_variant

CLI = [sys.executable, "-m", "benches.cli", "table"]


def cli(*args, bench=None):
    extra = ["--bench", str(bench)] if bench else []
    return subprocess.run(CLI + extra + list(args), cwd=REPO_ROOT, capture_output=True, text=True, timeout=120)


@pytest.mark.parametrize("transport", ["in-process", "loopback"])
def test_jog_commands_on_the_simulated_bench(transport):
    r = cli("--transport", transport, "idn")
    assert r.returncode == 0 and "Acutrol3000" in r.stdout
    r = cli("--transport", transport, "move", "10", "-20", "370")
    assert r.returncode == 0, r.stderr
    assert "settled" in r.stdout and "inner 370.0000°" in r.stdout and "IN_POSITION" in r.stdout
    r = cli("--transport", transport, "spin", "middle", "-12.5")
    assert r.returncode == 0 and "turning at -12.5 °/s" in r.stdout and "table --bench" in r.stdout
    assert r.stdout.rstrip().endswith("stop")
    r = cli("--transport", transport, "status")
    assert r.returncode == 0 and "modes stop/stop/stop" in r.stdout and "controller limits, inner: rate 360" in r.stdout
    r = cli("--transport", transport, "stop")
    assert r.returncode == 0 and "at rest" in r.stdout


@pytest.mark.parametrize(
    "args,message",
    [
        (("spin", "inner", "500"), "exceeds the inner axis limit 400 °/s; nothing was sent"),
        (("spin", "sideways", "5"), "not one of outer, middle, inner"),
        (("move", "1", "2"), "needs 3 value(s)"),
        (("move", "1", "nan", "3"), "not a finite number"),
    ],
)
def test_bad_demands_are_refused_before_sending(args, message):
    r = cli(*args)
    assert r.returncode == 2 and message in r.stderr and len(r.stderr.strip().splitlines()) == 1


def test_position_limits_checked(tmp_path):
    bench = bench_variant(
        tmp_path,
        lim=(
            "middle: {rate_max_dps: 300.0, accel_max_dps2: 80.0}",
            "middle: {rate_max_dps: 300.0, accel_max_dps2: 80.0, position_min_deg: -90, position_max_deg: 90}",
        ),
    )
    r = cli("move", "0", "120", "0", bench=bench)
    assert r.returncode == 2 and "outside the bench limits [-90°, 90°]; nothing was sent" in r.stderr


def test_latched_interlock_fault_gives_one_line_and_exit_1(tmp_path):
    bench = bench_variant(
        tmp_path, f=("  controller: acutrol", "  controller: acutrol\n  faults: [{time_s: 0.5, fault: STALL}]")
    )
    r = cli("move", "90", "0", "0", bench=bench)
    assert r.returncode == 1
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1, r.stderr
    assert "interlock fault latched" in lines[0] and "'Fault'" in lines[0] and "axes commanded Off" in lines[0]
    r = cli("status", bench=bench)  # a fresh simulated world: nothing latched
    assert r.returncode == 0


def _args(action, *values, transport="loopback"):
    return argparse.Namespace(
        bench=None, transport=transport, seed=None, timeout=None, action=action, values=list(values)
    )


def test_dropped_link_gives_one_line_and_exit_1(monkeypatch, capsys):
    orig = factory.open_table

    def open_and_drop(config, **kw):
        bench = orig(config, **kw)
        world = bench.world
        calls = {"n": 0}
        produce = world.produce

        def produce_then_drop(n):
            calls["n"] += 1
            if calls["n"] == 5:
                bench._closers[0].__self__.disconnect()  # the simulated controller drops the link mid-move
            return produce(n)

        monkeypatch.setattr(world, "produce", produce_then_drop)
        return bench

    monkeypatch.setattr(factory, "open_table", open_and_drop)
    code = cmd.run(_args("move", "0", "0", "300"), out=io.StringIO())
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 1 and len(err) == 1
    assert err[0].startswith("tablebench table: link lost:") and "could not command Off" in err[0]


@pytest.mark.parametrize("sig", ["SIGHUP", "SIGTERM", "SIGINT"])
def test_signal_during_a_move_stops_the_axes(monkeypatch, capsys, sig):
    state = {}
    orig = factory.open_table

    def open_and_signal(config, **kw):
        bench = orig(config, **kw)
        state["bench"] = bench
        world = bench.world
        produce = world.produce
        calls = {"n": 0}

        def produce_then_signal(n):
            calls["n"] += 1
            if calls["n"] == 3:
                os.kill(os.getpid(), getattr(signal, sig))
            return produce(n)

        monkeypatch.setattr(world, "produce", produce_then_signal)
        return bench

    monkeypatch.setattr(factory, "open_table", open_and_signal)
    code = cmd.run(_args("move", "0", "0", "300", transport="in-process"), out=io.StringIO())
    err = capsys.readouterr().err.strip()
    assert code == 130 and f"interrupted ({sig}); axes commanded Off" in err
    world = state["bench"].world
    world.produce(5000)
    s = world.table_state()
    assert all(abs(r) < 1e-9 for r in s.rates) and abs(math.degrees(s.angles[2])) < 300

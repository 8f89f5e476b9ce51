"""A lab's shared database: two benches adding at the same moment lose nothing and duplicate nothing.

Two processes run ``tablebench registry add`` over 100 runs each, on an empty database (both also create its
schema at the same moment): A adds runs 1–100 in order, B runs 51–150 in reverse order, so they collide on
50 runs from opposite ends. Afterwards: exactly 150 calibrations, 150 × 18 parameters, one unit, one bench.
"""

from __future__ import annotations

import os
import subprocess
import sys

import sqlalchemy as sa

from benches.results.registry import Registry
from benches.results.registry import schema as S
from tests.benches.registry.runs import RunFactory

CLI = [sys.executable, "-m", "benches.cli"]
UG = 9.80665e-6


def test_two_processes_adding_100_runs_each_lose_nothing_and_duplicate_nothing(tmp_path, registry_url):
    f = RunFactory(tmp_path)
    runs = [f.make(f"r{k:03d}", shift={"b_x": k * UG}, created_utc=f"2026-01-01T00:{k // 60:02d}:{k % 60:02d}Z")
            for k in range(1, 151)]  # fmt: skip
    a = [str(r) for r in runs[:100]]
    b = [str(r) for r in runs[50:]][::-1]
    env = dict(os.environ, TABLEBENCH_OPERATOR="concurrency")
    procs = [
        subprocess.Popen([*CLI, "registry", "add", *names, "--registry", registry_url], cwd=tmp_path, env=env,
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)  # fmt: skip
        for names in (a, b)
    ]
    outs = [p.communicate(timeout=1200) for p in procs]
    for p, (out, err) in zip(procs, outs, strict=True):
        assert p.returncode == 0, err
        assert len(out.splitlines()) == 100
    added = sum(o.count(": added") for o, _ in outs)
    assert added == 150  # every run added exactly once, by one of the two
    reg = Registry(registry_url)
    with reg.connect() as conn:
        def n(t):
            return conn.execute(sa.select(sa.func.count()).select_from(t)).scalar_one()

        assert (n(S.calibrations), n(S.parameters), n(S.units), n(S.benches)) == (150, 150 * 18, 1, 1)
        digests = conn.execute(sa.select(S.calibrations.c.digest)).scalars().all()
        folders = conn.execute(sa.select(S.calibrations.c.run_folder)).scalars().all()
    assert len(set(digests)) == 150 and sorted(folders) == sorted(str(r) for r in runs)

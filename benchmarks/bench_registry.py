"""Benchmark: the calibration registry with 10 000 calibrations — ``registry show`` and ``trend`` against the
same query in plain SQL (issue 27; a technician waits well under a second).

The store: 100 units × 100 whole-unit calibrations (10 000 calibrations, 330 000 parameter rows: the
accelerometer's 18 and the gyro's 15, each calibration with its 33 × 33 covariance as JSON), bulk-inserted
through the registry's own schema (SQLite file; and PostgreSQL when its binaries are installed, on a throw-away
server). For one unit (100 calibrations):

- ``show``: the registry's history query and the history table (:func:`queries.history` +
  :func:`report.history_table`) against one plain-SQL ``SELECT … JOIN …`` of the same columns through the
  bare DB-API driver (sqlite3 / psycopg), fetched into Python;
- ``trend``: the registry's series query with the control limits and E_n (no figure) against the plain-SQL
  series; and the whole ``trend`` work with the PNG, and the whole command as a process (what the technician
  waits for), in seconds.

Ratios are medians of alternated repeats in the same run. Section "registry" of benchmarks/RESULTS.md.
"""

from __future__ import annotations

import argparse
import json
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from analysis.identification.specification import get_model
from benches.results.registry import Registry
from benches.results.registry import schema as S
from benches.results.registry.queries import history, series
from benches.results.registry.report import en_between, history_table, plot_trend
from benches.results.registry.stats import control_limits
from benchmarks._results import write_section

UNITS, PER_UNIT = 100, 100
_ACC, _GYRO = get_model("accelerometer"), get_model("gyro")
NAMES = (*_ACC.names, *_GYRO.names)
"""A whole-unit calibration's parameters (accelerometer and gyro triads: 33), as ``run`` records them."""
KINDS = (*_ACC.kinds, *_GYRO.kinds)
NP = len(NAMES)


def populate(reg: Registry, seed: int = 1) -> None:
    """UNITS × PER_UNIT synthetic calibrations (SI values around a typical unit, one month apart)."""
    rng = np.random.default_rng(seed)
    cov = json.dumps((np.eye(NP) * 1e-12).tolist(), separators=(",", ":"))
    names = json.dumps(list(NAMES))
    with reg.begin() as conn:
        conn.execute(S.units.insert(), [{"id": u + 1, "serial": f"U-{u:04d}", "model": "SIM-QA",
                                          "configuration": "1"} for u in range(UNITS)])  # fmt: skip
        conn.execute(S.benches.insert(), [{"id": b + 1, "name": f"lab-{b}", "table_model": "T",
                                            "table_serial": f"T{b}"} for b in range(3)])  # fmt: skip
        cid = 0
        for u in range(UNITS):
            cals, params = [], []
            base = rng.normal(0, 1e-4, NP)
            for k in range(PER_UNIT):
                cid += 1
                month = k % 12 + 1
                cals.append({
                    "id": cid, "digest": f"{cid:064x}", "recording_sha256": f"{cid:064x}", "unit_id": u + 1,
                    "bench_id": k % 3 + 1, "run_folder": f"/runs/u{u}/{k}", "run_utc": f"{2000 + k // 12:04d}-"
                    f"{month:02d}-01T00:00:00Z", "recorded_utc": "2026-01-01T00:00:00Z", "procedure_name": "ten-step",
                    "procedure_sha256": "0" * 64, "method": "kalman", "status": "complete", "operator": "bench",
                    "software_version": "0.1.0", "parameter_names": names, "covariance": cov,
                    "decision": "PASS", "certificate_number": f"TB-{cid:06d}", "supersedes": "",
                })  # fmt: skip
                x = base + rng.normal(0, 1e-6, NP)
                params += [{"calibration_id": cid, "name": n, "kind": KINDS[i], "value": float(x[i]),
                            "u": 1e-6, "expanded": 2e-6, "identified": True, "budget": None}
                           for i, n in enumerate(NAMES)]  # fmt: skip
            conn.execute(S.calibrations.insert(), cals)
            conn.execute(S.parameters.insert(), params)


PLAIN_SHOW = (
    "SELECT c.id, c.run_utc, c.run_folder, c.digest, c.recording_sha256, c.procedure_name, c.procedure_sha256, "
    "c.method, c.status, c.operator, c.decision, c.certificate_number, c.supersedes, c.covariance, "
    "c.certificate_covariance, c.as_found, c.as_left, c.as_found_of, u.serial, u.model, u.configuration, "
    "b.name, p.name, p.value, p.u, p.expanded, p.identified, p.budget "
    "FROM calibrations c JOIN units u ON c.unit_id = u.id JOIN benches b ON c.bench_id = b.id "
    "JOIN parameters p ON p.calibration_id = c.id WHERE u.serial = {ph} ORDER BY c.run_utc, c.id"
)
PLAIN_TREND = (
    "SELECT c.run_utc, p.value, p.u, p.expanded, p.identified FROM parameters p "
    "JOIN calibrations c ON p.calibration_id = c.id JOIN units u ON c.unit_id = u.id "
    "WHERE u.serial = {ph} AND p.name = {ph} ORDER BY c.run_utc, c.id"
)


def plain(url: str, sql: str, args: tuple) -> list:
    """The query through the bare DB-API driver (a new connection, as a command would open)."""
    if url.startswith("sqlite"):
        import sqlite3

        con = sqlite3.connect(url.split(":///", 1)[1])
        try:
            return con.execute(sql.format(ph="?"), args).fetchall()
        finally:
            con.close()
    import psycopg

    with psycopg.connect(url.replace("postgresql+psycopg://", "postgresql://")) as con:
        return con.execute(sql.format(ph="%s"), args).fetchall()


def ours_show(url: str, serial: str) -> str:
    reg = Registry(url)
    try:
        return history_table(history(reg, serial))
    finally:
        reg.close()


def ours_trend(url: str, serial: str) -> list:
    reg = Registry(url)
    try:
        s = series(reg, serial, "b_x")
        control_limits([p["value"] for p in s if p["identified"]])
        return s
    finally:
        reg.close()


def timed(fn, *a, **kw) -> float:  # noqa: ANN001, ANN003
    t0 = time.perf_counter()
    fn(*a, **kw)
    return time.perf_counter() - t0


def process(cmd: list[str]) -> tuple[float, float]:
    """(wall, CPU) seconds of one command as a process (CPU: user + system of the child)."""
    r0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    p = subprocess.run(cmd, capture_output=True, check=False)
    wall = time.perf_counter() - t0
    r1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    if p.returncode != 0:
        raise SystemExit(f"{' '.join(cmd)}: exit {p.returncode}: {p.stderr.decode()[-500:]}")
    return wall, (r1.ru_utime - r0.ru_utime) + (r1.ru_stime - r0.ru_stime)


def measure(url: str, repeats: int, tmp: Path) -> dict[str, float]:
    serial = "U-0042"
    out: dict[str, list[float]] = {k: [] for k in ("show", "show_sql", "trend", "trend_sql")}
    for _ in range(repeats):  # alternated
        out["show"].append(timed(ours_show, url, serial))
        out["show_sql"].append(timed(plain, url, PLAIN_SHOW, (serial,)))
        out["trend"].append(timed(ours_trend, url, serial))
        out["trend_sql"].append(timed(plain, url, PLAIN_TREND, (serial, "b_x")))
    med = {k: statistics.median(v) for k, v in out.items()}
    reg = Registry(url)
    rows = history(reg, serial)
    en_between(rows[0], rows[1])
    med["trend_png"] = statistics.median(timed(plot_trend, rows, "b_x", tmp / "t.png") for _ in range(3))
    reg.close()
    cli = [sys.executable, "-m", "benches.cli", "registry"]
    cmds = {
        "pass": [sys.executable, "-c", "pass"],
        "floor": [sys.executable, "-c", "import sqlalchemy, numpy"],
        "cli_show": [*cli, "show", serial, "--registry", url],
        "cli_trend": [*cli, "trend", serial, "--param", "b_x", "--out", str(tmp / "c.png"), "--registry", url],
    }
    proc: dict[str, list[tuple[float, float]]] = {k: [] for k in cmds}
    for _ in range(5):  # alternated
        for k, c in cmds.items():
            proc[k].append(process(c))
    for k, v in proc.items():
        med[k] = statistics.median(w for w, _ in v)
        med[k + "_cpu"] = statistics.median(c for _, c in v)
    return med


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=15)
    args = ap.parse_args()
    tmp = Path(tempfile.mkdtemp(prefix="tb-registry-bench-"))
    engines: dict[str, str] = {"SQLite": f"sqlite:///{tmp / 'registry.sqlite'}"}
    server = None
    try:
        from tests.benches.registry.pgserver import PostgresServer, find_binaries

        bindir = find_binaries()
        if bindir is not None:
            server = PostgresServer(bindir)
            server.start()
            engines["PostgreSQL 15"] = server.new_database()
    except Exception as exc:  # noqa: BLE001 - the benchmark still reports SQLite
        print(f"PostgreSQL not measured: {exc}", file=sys.stderr)
    rows = []
    try:
        for name, url in engines.items():
            t0 = time.perf_counter()
            populate(Registry(url))
            fill = time.perf_counter() - t0
            m = measure(url, args.repeats, tmp)
            rows.append((name, fill, m))
            print(name, {k: round(v, 4) for k, v in m.items()}, file=sys.stderr)
    finally:
        if server is not None:
            server.stop()
    import os

    load = os.getloadavg()[0]
    body = [
        f"{UNITS} units × {PER_UNIT} calibrations = {UNITS * PER_UNIT} whole-unit calibrations "
        f"({UNITS * PER_UNIT * NP} parameter rows: the accelerometer's 18 and the gyro's 15 each, with the "
        f"{NP} × {NP} covariance); one unit's history (100 calibrations). Medians of {args.repeats} alternated "
        "repeats; each call opens the registry as a command does. Plain SQL: the same rows by one hand-written "
        "JOIN through the bare DB-API "
        "driver (sqlite3 / psycopg).",
        "",
        "| engine | fill (s) | show (ms) | plain SQL (ms) | ratio | trend query (ms) | plain SQL (ms) | ratio | "
        "trend + PNG (ms) |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for name, fill, m in rows:
        body.append(
            f"| {name} | {fill:.1f} | {m['show'] * 1e3:.1f} | {m['show_sql'] * 1e3:.1f} | "
            f"{m['show'] / m['show_sql']:.1f}× | {m['trend'] * 1e3:.1f} | {m['trend_sql'] * 1e3:.1f} | "
            f"{m['trend'] / m['trend_sql']:.1f}× | {m['trend_png'] * 1e3:.0f} |"
        )
    body += [
        "",
        "What the technician waits for — the whole command as a process (Python start-up, imports, opening the "
        "registry, query, table or figure), medians of 5 alternated runs, wall and CPU (user + system) seconds; "
        "the floor is `python -c \"import sqlalchemy, numpy\"` (any SQLAlchemy program's start-up), measured in "
        "the same alternation:",
        "",
        "| engine | `python -c pass` wall / CPU | floor wall / CPU | `registry show` wall / CPU | "
        "`registry trend` (PNG) wall / CPU |",
        "|---|---|---|---|---|",
    ]
    for name, _fill, m in rows:
        body.append(
            f"| {name} | {m['pass']:.2f} / {m['pass_cpu']:.2f} | {m['floor']:.2f} / {m['floor_cpu']:.2f} | "
            f"{m['cli_show']:.2f} / {m['cli_show_cpu']:.2f} | {m['cli_trend']:.2f} / {m['cli_trend_cpu']:.2f} |"
        )
    body += [
        "",
        f"Machine: 2 cores, load average {load:.1f} at the end"
        + (" (shared with other jobs: wall times are then several times an idle PC's; the CPU column, the work "
           "the command does, is inflated far less). " if load > 1.5 else " (quiet). ")
        + "show/trend include opening the registry (engine, schema-version check read from "
        "Alembic's table without importing Alembic) and, for show, the history table with s_r/s_R per parameter.",
    ]
    title = "Calibration registry: show and trend with 10 000 calibrations (issue 27)"
    write_section("registry", title, "\n".join(body))


if __name__ == "__main__":
    main()

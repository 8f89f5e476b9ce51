"""The calibration registry on SQLite and on a real PostgreSQL server: contents, idempotence, as found,
exports identical on both engines, schema upgrade of a populated database, the commands."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest
import sqlalchemy as sa

from analysis.identification.model import PARAM_NAMES, correct
from benches.results.registry import Registry, RegistryError, add_run
from benches.results.registry import schema as S
from benches.results.registry.queries import by_run, history, series
from benches.results.registry.report import export_text
from tests.benches.registry.conftest import ENGINES
from tests.benches.registry.runs import RunFactory, value

CLI = [sys.executable, "-m", "benches.cli"]
UG = 9.80665e-6


@pytest.fixture(scope="module")
def factory(tmp_path_factory) -> RunFactory:
    return RunFactory(tmp_path_factory.mktemp("registry-runs"))


def _three_runs(factory: RunFactory, tag: str):
    r1 = factory.make(f"{tag}-1", created_utc="2026-01-10T09:00:00Z")
    r2 = factory.make(f"{tag}-2", created_utc="2026-04-10T09:00:00Z", shift={"b_x": 50 * UG})
    r3 = factory.make(f"{tag}-3", created_utc="2026-07-10T09:00:00Z", shift={"b_x": 100 * UG, "S_y": 20e-6})
    return r1, r2, r3


def test_a_run_is_recorded_once_with_every_parameter_and_its_covariance(factory, registry_url):
    run = factory.make(f"once-{registry_url[:6]}", created_utc="2026-02-01T10:00:00Z")
    reg = Registry(registry_url)
    first = add_run(reg, run, operator="A. Tech")
    again = add_run(reg, run, operator="someone else")
    assert first.added and not again.added and again.calibration_id == first.calibration_id
    assert reg.count() == 1
    [row] = history(reg, "SIM-U-0001")
    cal = json.loads((run / "calibration.json").read_text())
    assert row.operator == "A. Tech" and row.run_utc == "2026-02-01T10:00:00Z" and row.bench == cal["run"]["bench_name"]
    assert row.recording_sha256 == cal["recording_sha256"] and row.configuration == "1"
    assert np.array_equal(row.values, [cal["parameters"][n]["value"] for n in PARAM_NAMES])  # exact round trip
    assert json.loads(row.covariance) == cal["covariance"]
    assert row.decision is None and row.certificate_number is None  # not certified yet
    with reg.connect() as conn:
        assert conn.execute(sa.select(sa.func.count()).select_from(S.parameters)).scalar_one() == 18
        assert conn.execute(sa.select(sa.func.count()).select_from(S.units)).scalar_one() == 1


def test_as_found_is_the_previous_calibration_applied_to_this_runs_data(factory, registry_url):
    """A later calibration whose bias b_x is δ larger: under the previous calibration (as found) every step's
    x residual is δ larger than under its own (as left), y and z unchanged — the model's bias adds to f_out."""
    r1, r2, _ = _three_runs(factory, f"af-{registry_url[:6]}")
    reg = Registry(registry_url)
    add_run(reg, r1)
    add_run(reg, r2)
    first, second = history(reg, "SIM-U-0001")
    assert first.as_found is None and first.as_left is not None  # nothing before the first
    found, left = json.loads(second.as_found), json.loads(second.as_left)
    assert second.as_found_of == first.id and found["run_utc"] == first.run_utc
    delta = value(r2, "b_x") - value(r1, "b_x")
    assert delta == pytest.approx(50 * UG)
    for step, m in found["steps"].items():
        d = np.subtract(m, left["steps"][step])
        assert d[0] == pytest.approx(delta, rel=1e-6) and abs(d[1]) < 1e-12 and abs(d[2]) < 1e-12


def test_history_series_and_compare_by_run_folder_or_digest(factory, registry_url):
    r1, r2, r3 = _three_runs(factory, f"hs-{registry_url[:6]}")
    reg = Registry(registry_url)
    for r in (r3, r1, r2):  # added out of order: history is by run time
        add_run(reg, r)
    rows = history(reg, "SIM-U-0001")
    assert [r.run_folder for r in rows] == [str(r1), str(r2), str(r3)]
    s = series(reg, "SIM-U-0001", "b_x")
    assert [p["value"] for p in s] == [value(r, "b_x") for r in (r1, r2, r3)]
    assert by_run(reg, str(r2)).digest == by_run(reg, rows[1].digest[:12]).digest
    with pytest.raises(RegistryError, match="no such run"):
        by_run(reg, "0123456789abcdef")
    with pytest.raises(RegistryError, match="not a parameter"):
        series(reg, "SIM-U-0001", "b_w")


def test_export_is_identical_from_both_engines_and_applies_with_the_equation_of_correct(factory, tmp_path, request):
    """Same calibrations into every engine available (SQLite and PostgreSQL): byte-identical JSON and CSV."""
    runs = _three_runs(factory, "export")
    texts = {}
    for engine in ENGINES:
        url = f"sqlite:///{tmp_path / 'e.sqlite'}" if engine == "sqlite" else request.getfixturevalue(
            "pg_server").new_database()  # fmt: skip
        reg = Registry(url)
        for r in runs:
            add_run(reg, r, operator="A. Tech")
        rows = history(reg, "SIM-U-0001")
        texts[engine] = (export_text(rows, "json"), export_text(rows, "csv"))
    if len(ENGINES) == 2:
        assert texts["sqlite"] == texts["postgresql"]
    doc = json.loads(texts["sqlite"][0])
    assert doc["parameter_names"] == list(PARAM_NAMES) and len(doc["calibrations"]) == 3
    # the export's compensation gives what `correct` gives from the run's calibration.json
    from benches.cli.commands.correct import load_calibration_vector

    x_cal, _ = load_calibration_vector(runs[2] / "calibration.json")
    comp = doc["calibrations"][2]["compensation"]
    x_exp = np.where(comp["use"], comp["x_si"], 0.0)
    f_out = np.array([[0.1, -0.2, 9.81], [9.8, 0.05, 0.3]])
    omega = np.array([[0.0, 0.0, 0.5], [0.1, 0.0, 0.0]])
    assert np.array_equal(correct(x_exp, f_out, omega), correct(x_cal, f_out, omega))
    u0, u1 = (doc["calibrations"][k]["parameters"]["b_x"]["U"] for k in (0, 1))
    assert doc["calibrations"][1]["en_vs_previous"]["b_x"] == pytest.approx(50 * UG / np.hypot(u0, u1))


def test_a_populated_database_of_the_previous_schema_is_upgraded_keeping_every_row(registry_url):
    reg = Registry(registry_url, upgrade=False)
    reg.upgrade("0001")
    assert reg.revision() == "0001"
    units = sa.table("units", sa.column("id"), sa.column("serial"), sa.column("model"), sa.column("configuration"))
    benches = sa.table("benches", sa.column("id"), sa.column("name"), sa.column("table_model"),
                       sa.column("table_serial"))  # fmt: skip
    cols = ["id", "recording_sha256", "unit_id", "bench_id", "run_folder", "run_utc", "recorded_utc",
            "procedure_name", "procedure_sha256", "method", "status", "operator", "software_version",
            "parameter_names", "covariance", "decision", "certificate_number", "supersedes"]  # fmt: skip
    cals = sa.table("calibrations", *[sa.column(c) for c in cols])
    params = sa.table("parameters", *[sa.column(c) for c in ("calibration_id", "name", "kind", "value", "u",
                                                                  "expanded", "identified", "budget")])  # fmt: skip
    cov = json.dumps(np.eye(18).tolist())
    with reg.begin() as conn:
        conn.execute(sa.insert(units), [{"id": 1, "serial": "U-7", "model": "M", "configuration": "1"}])
        conn.execute(sa.insert(benches), [{"id": 1, "name": "lab-1", "table_model": "T", "table_serial": "T1"}])
        conn.execute(sa.insert(cals), [
            {"id": k, "recording_sha256": f"{k:064x}", "unit_id": 1, "bench_id": 1, "run_folder": f"/runs/{k}",
             "run_utc": f"2025-0{k}-01T00:00:00Z", "recorded_utc": "2025-09-01T00:00:00Z", "procedure_name": "p",
             "procedure_sha256": "", "method": "kalman", "status": "complete", "operator": "op",
             "software_version": "0.0.9", "parameter_names": json.dumps(list(PARAM_NAMES)), "covariance": cov,
             "decision": "PASS" if k == 2 else None, "certificate_number": "TB-000002" if k == 2 else None,
             "supersedes": "" if k == 2 else None}
            for k in (1, 2)
        ])  # fmt: skip
        conn.execute(sa.insert(params), [
            {"calibration_id": k, "name": n, "kind": "bias", "value": 1e-4 * k + i * 1e-7, "u": 1e-6,
             "expanded": 2e-6, "identified": True, "budget": None}
            for k in (1, 2) for i, n in enumerate(PARAM_NAMES)
        ])  # fmt: skip
    reg.close()
    reg = Registry(registry_url)  # opening upgrades
    assert reg.revision() == S.SCHEMA_VERSION
    rows = history(reg, "U-7")
    assert [r.recording_sha256 for r in rows] == [f"{k:064x}" for k in (1, 2)]
    assert rows[0].values[0] == 1e-4 and rows[1].values[17] == 2e-4 + 17e-7
    assert [r.digest for r in rows] == ["v1-" + f"{k:064x}" for k in (1, 2)]
    assert rows[1].certificate_number == "TB-000002" and rows[1].decision == "PASS"
    with reg.connect() as conn:
        certs = conn.execute(sa.select(S.certificates)).all()
    assert [(c.number, c.calibration_id, c.verdict) for c in certs] == [("TB-000002", 2, "PASS")]


def _schema(engine: sa.Engine) -> dict:
    """Every table's columns (name, type, nullability, default), primary key, unique constraints, indexes and
    foreign keys (with their ON DELETE), as the database itself reports them."""
    i = sa.inspect(engine)
    return {
        t: {
            "columns": sorted(
                (c["name"], str(c["type"]), c["nullable"], str(c.get("default"))) for c in i.get_columns(t)
            ),
            "pk": i.get_pk_constraint(t),
            "unique": sorted((u["name"], tuple(u["column_names"])) for u in i.get_unique_constraints(t)),
            "indexes": sorted((x["name"], tuple(x["column_names"]), bool(x["unique"])) for x in i.get_indexes(t)),
            "foreign": sorted(
                (
                    f["name"] or "",
                    f["referred_table"],
                    tuple(f["constrained_columns"]),
                    tuple(f["referred_columns"]),
                    str(f.get("options")),
                )
                for f in i.get_foreign_keys(t)
            ),
        }  # fmt: skip
        for t in sorted(i.get_table_names())
    }


def test_a_new_database_created_directly_has_exactly_the_schema_the_migrations_give(registry_url, tmp_path, request):
    """Opening an empty database creates the newest schema from schema.py and stamps its revision (no Alembic
    run); running every migration on another empty database of the same engine gives the same tables, columns,
    keys, indexes and Alembic version table, and Alembic reads the stamped revision as the newest."""
    direct = Registry(registry_url)
    other = (f"sqlite:///{tmp_path / 'migrated.sqlite'}" if registry_url.startswith("sqlite")
             else request.getfixturevalue("pg_server").new_database())  # fmt: skip
    migrated = Registry(other, upgrade=False)
    migrated.upgrade(S.SCHEMA_VERSION)  # an explicit revision: always through Alembic's migrations
    assert migrated.revision() == direct.revision() == S.SCHEMA_VERSION
    got, want = _schema(direct.engine), _schema(migrated.engine)
    assert set(got) == set(want) == {"alembic_version", *S.metadata.tables}
    for table in want:
        assert got[table] == want[table], table
    Registry(registry_url)  # opening again changes nothing
    assert _schema(direct.engine) == got


def _cli(*args, cwd, env=None):
    return subprocess.run([*CLI, *args], cwd=cwd, capture_output=True, text=True, timeout=300, env=env)


def test_the_commands_and_their_bad_input(factory, tmp_path):
    r1, r2, r3 = _three_runs(factory, "cli")
    db = f"sqlite:///{tmp_path / 'cli.sqlite'}"
    p = _cli("registry", "add", str(r1), str(r2), str(r3), "--registry", db, cwd=tmp_path)
    assert p.returncode == 0, p.stderr
    assert p.stdout.count(": added") == 3
    p = _cli("registry", "add", str(r2), "--registry", db, cwd=tmp_path)
    assert p.returncode == 0 and "already recorded (nothing changed)" in p.stdout
    p = _cli("registry", "show", "SIM-U-0001", "--registry", db, cwd=tmp_path)
    assert p.returncode == 0 and "as found" in p.stdout and "s_r" in p.stdout
    png = tmp_path / "t" / "b_x.png"
    p = _cli("registry", "trend", "SIM-U-0001", "--param", "b_x", "--out", str(png), "--registry", db, cwd=tmp_path)
    assert p.returncode == 0, p.stderr
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    p = _cli("registry", "compare", str(r1), str(r3), "--registry", db, cwd=tmp_path)
    assert p.returncode == 0 and "E_n" in p.stdout and "disagree" in p.stdout
    p = _cli("registry", "due", "--now", "2026-08-01", "--registry", db, cwd=tmp_path)
    assert p.returncode == 0 and "SIM-U-0001" in p.stdout and "method 1" in p.stdout
    bad = [
        ("registry", "show", "NO-SUCH-UNIT", "--registry", db),
        ("registry", "trend", "SIM-U-0001", "--param", "b_w", "--out", "x.png", "--registry", db),
        ("registry", "compare", str(r1), "feedfacefeedface", "--registry", db),
        ("registry", "due", "--now", "tomorrow", "--registry", db),
        ("registry", "add", str(tmp_path / "nowhere"), "--registry", db),
        ("registry", "list", "--registry", str(tmp_path / "absent.sqlite")),
        ("registry", "list", "--registry", "postgresql://nobody@127.0.0.1:1/none"),
        ("registry", "list", "--registry", "mysql+nodriver://x/y"),
        ("registry", "export", "SIM-U-0001", "--out", str(tmp_path), "--registry", db),
    ]
    for args in bad:
        p = _cli(*args, cwd=tmp_path)
        assert p.returncode == 2, (args, p.stdout, p.stderr)
        lines = p.stderr.strip().splitlines()
        assert len(lines) == 1 and "Traceback" not in p.stderr, (args, p.stderr)


def test_a_history_mixing_accelerometer_only_and_whole_unit_calibrations(factory, registry_url):
    """An older accelerometer-only calibration and a whole-unit one (gyro parameters too) in one history: the
    history has every parameter of either; the older one has none of the gyro's (NaN, not identified), compare
    and E_n skip them, the export says null — on both engines."""
    from benches.results.registry.record import canonical, run_record
    from benches.results.registry.report import compare_table, en_between

    r1, r2, _ = _three_runs(factory, f"mix-{registry_url[:6]}")
    reg = Registry(registry_url)
    add_run(reg, r1)
    rec = run_record(r2)
    gyro = [("gyro_b_x", "gyro_bias", 2.4e-6, 1.0e-7), ("gyro_S_y", "gyro_scale", 35e-6, 2e-6)]
    rec["parameters"] += [{"name": n, "kind": k, "value": v, "u": u, "expanded": 2 * u, "identified": True,
                           "budget": None} for n, k, v, u in gyro]  # fmt: skip
    names = [p["name"] for p in rec["parameters"]]
    rec["calibration"]["parameter_names"] = canonical(names)
    reg.add(rec)
    old, new = history(reg, "SIM-U-0001")
    assert list(old.names) == list(new.names) == names
    i = names.index("gyro_S_y")
    assert np.isnan(old.values[i]) and not old.identified[i]
    assert new.values[i] == 35e-6 and new.identified[i] and new.kinds[i] == "gyro_scale"
    en = en_between(old, new)
    assert en["gyro_S_y"] is None and en["b_x"] is not None
    assert "gyro_S_y" in compare_table(old, new)
    doc = json.loads(export_text([old, new], "json"))
    assert doc["calibrations"][0]["parameters"]["gyro_S_y"]["value"] is None
    assert doc["calibrations"][1]["parameters"]["gyro_S_y"]["value"] == 35e-6
    assert [p["value"] for p in series(reg, "SIM-U-0001", "gyro_b_x")] == [2.4e-6]

"""One typed run: ``tablebench run`` parses the bench once and compiles the procedure once; the recorded run is
opened once for identification and certificate; calibration.json's blocks are typed and round-trip."""

from __future__ import annotations

import json

import benches.bench_config as bench_config
import benches.recorded_run as recorded_run
import benches.session as session
from benches.calibration_result import CalibrationResult, InformationSummary, Residuals, RunInfo, TruthCheck
from benches.cli import main
from benches.identify import identify_run
from benches.recorded_run import open_run
from tests.simbench import short_ten_step


def _counting(monkeypatch, module, name, counter):
    real = getattr(module, name)

    def wrapper(*a, **k):
        counter[name] = counter.get(name, 0) + 1
        return real(*a, **k)

    monkeypatch.setattr(module, name, wrapper)


def test_one_run_parses_the_bench_once_and_compiles_the_procedure_once(tmp_path, monkeypatch, capsys):
    proc = tmp_path / "short.yaml"
    proc.write_text(short_ten_step(hold_s=1, warmup_s=2), encoding="utf-8")
    calls: dict[str, int] = {}
    _counting(monkeypatch, bench_config, "_build", calls)  # every bench parse goes through it
    _counting(monkeypatch, session, "compile_procedure", calls)
    _counting(monkeypatch, recorded_run, "compile_procedure", calls)
    opened: list[object] = []
    real_open = session.open_run
    monkeypatch.setattr(session, "open_run", lambda *a, **k: opened.append(1) or real_open(*a, **k))
    out = tmp_path / "run"
    assert main(["run", "--procedure", str(proc), "--seed", "2", "--out", str(out), "--plain"]) == 0
    assert calls == {"_build": 1, "compile_procedure": 1}
    assert len(opened) == 1
    assert (out / "calibration.json").exists() and any(out.glob("certificate*.pdf"))
    # the typed blocks of what was written, and the same result offline (same recording, no live filter)
    cal = CalibrationResult.load(out / "calibration.json")
    assert isinstance(cal.information, InformationSummary) and cal.information.rank == len(cal.parameters) == 33
    assert isinstance(cal.residuals, Residuals) and cal.residuals.per_step
    assert cal.per_step[0]["kind"] in ("hold", "spin")
    assert isinstance(cal.run, RunInfo) and cal.run.status == "complete"
    assert isinstance(cal.truth, TruthCheck)
    assert cal.truth.dof == len(cal.parameters) - len(cal.information.unidentifiable)
    assert cal.live_vs_offline_max_u is not None and cal.extra == {}
    offline = identify_run(out).to_dict()
    written = json.loads((out / "calibration.json").read_text(encoding="utf-8"))
    written.pop("live_vs_offline_max_u")
    seal = written.pop("integrity")  # the tamper-evidence block save() adds (benches/calibration_integrity.py)
    assert seal["recording_sha256"] == written["recording_sha256"] and len(seal["values_sha256"]) == 64
    assert offline == written
    # the recorded run, typed: header, the parsed bench and the compiled procedure of the recording
    with open_run(out) as rr:
        assert rr.header.status == "complete" and rr.compiled is not None
        assert len(rr.compiled.steps) == len(rr.steps) and rr.config.name == cal.run.bench_name
        assert identify_run(rr).to_dict() == offline


def test_unknown_keys_and_blocks_round_trip(tmp_path):
    """Keys this version does not know stay where they were (another version's file is not altered)."""
    from tests.benches.test_calibration_result import _result

    d = _result().to_dict()
    d["information"]["future_key"] = [1, 2]
    d["another_tool"] = {"a": 1}
    d["residuals"] = {"rms": [1.0, 2.0, 3.0], "per_step": [{"name": "A", "samples": 3, "mean": [0, 0, 0],
                                                          "rms": [1, 1, 1], "kind": "hold", "x": 1}]}  # fmt: skip
    back = CalibrationResult.from_dict(json.loads(json.dumps(d))).to_dict()
    assert back == d

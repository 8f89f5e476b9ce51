"""`tablebench run` says where the calibration went, stage by stage: the calibration's line as soon as the run
folder has calibration.json, then the registry's own line when it has recorded it, then the certificate; a
registry that cannot record costs one line and loses nothing; an interruption while the registry records says
what is left and the calibration stays in the run folder."""

from __future__ import annotations

import pytest

from benches.results.registry.sink import RegistrySink
from tests.simbench import bench_variant, short_ten_step


@pytest.fixture(scope="module")
def inputs(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("result-lines")
    bench = bench_variant(tmp, rate=100.0)
    proc = tmp / "short.yaml"
    proc.write_text(short_ten_step(hold_s=2, warmup_s=5, name="short"), encoding="utf-8")
    return tmp, ["--bench", str(bench), "--procedure", str(proc), "--plain", "--seed", "4"]


def _run(args, monkeypatch, capsys, registry: str):
    from benches.cli import main

    monkeypatch.setenv("TABLEBENCH_REGISTRY", registry)
    capsys.readouterr()
    code = main(["run", *args])
    out, err = capsys.readouterr()
    return code, out.splitlines(), err.splitlines()


def test_the_calibration_line_then_the_registry_line_then_the_certificate(inputs, monkeypatch, capsys):
    tmp, common = inputs
    db = tmp / "lab" / "registry.sqlite"
    folder = tmp / "ok"
    code, out, err = _run([*common, "--out", str(folder)], monkeypatch, capsys, str(db))
    assert code == 0, err[-20:]
    heads = [ln.split(":", 1)[0] for ln in out]
    assert heads == ["recording", "calibration", "registry", "registry", "certificate"], out
    assert out[1] == f"calibration: {folder / 'calibration.json'}"
    assert out[2].startswith("registry: SIM-U-0001") and "calibration 1 of 1" in out[2]
    assert out[2].endswith(f" in {db}")
    assert out[3].startswith("registry: certificate TB-") and out[3].endswith(f" in {db}")
    assert not [ln for ln in err if ln.startswith("registry")]


def test_a_registry_that_cannot_record_costs_one_line_and_the_run_folder_keeps_everything(
    inputs, monkeypatch, capsys
):
    tmp, common = inputs
    folder = tmp / "down"
    (tmp / "not-a-folder").write_text("x")
    code, out, err = _run([*common, "--out", str(folder)], monkeypatch, capsys, str(tmp / "not-a-folder" / "r.sqlite"))
    assert code == 0, err[-20:]
    assert [ln.split(":", 1)[0] for ln in out] == ["recording", "calibration", "certificate"], out
    said = [ln for ln in err if ln.startswith("registry")]
    assert len(said) == 1, err  # one line for the run (not one per result)
    assert "not recorded" in said[0] and f"tablebench registry add {folder}" in said[0]
    assert (folder / "calibration.json").exists() and (folder / "certificate.pdf").exists()


@pytest.mark.parametrize("certificate", [True, False], ids=["with-certificate", "no-certificate"])
def test_an_interruption_while_the_registry_records_keeps_the_calibration_and_says_what_is_left(
    inputs, monkeypatch, capsys, certificate
):
    tmp, common = inputs
    folder = tmp / f"stopped-{certificate}"

    def interrupted(self, doc):
        raise KeyboardInterrupt

    monkeypatch.setattr(RegistrySink, "calibration", interrupted)
    args = [*common, "--out", str(folder)] + ([] if certificate else ["--no-certificate"])
    code, out, err = _run(args, monkeypatch, capsys, str(tmp / "lab2.sqlite"))
    assert code == 130
    assert out[-1] == f"calibration: {folder / 'calibration.json'}" and (folder / "calibration.json").exists()
    [said] = [ln for ln in err if ln.startswith("interrupted while the registry")]
    assert said.endswith(f"record it later with: tablebench registry add {folder}")
    if certificate:  # the certificate is left; resuming issues it (and records the run in the registry)
        assert any("not done: certificate" in ln for ln in err), err[-5:]
        assert any(f"tablebench run --resume {folder}" in ln for ln in err)
    else:  # nothing of the run is left, only the registry's record
        assert err[-1] == f"interrupted after the results were written ({folder} is complete)"
        assert not any("not done" in ln for ln in err)

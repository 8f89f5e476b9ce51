"""Tamper evidence of calibration.json (issue 27): edited values, a removed digest and absurd values are refused
by `certificate`, `correct` and `registry add` in one line (exit 2); an untouched file is accepted however it
is indented; the registry stores the digest."""

from __future__ import annotations

import json

import numpy as np
import pytest

from benches.calibration_integrity import CalibrationTamperedError, load_verified, with_integrity
from benches.calibration_result import CalibrationResult
from benches.cli import main
from benches.results.registry import Registry
from benches.results.registry.queries import history
from tests.certificate_fixtures import make_run_folder


@pytest.fixture(scope="module")
def sealed(tmp_path_factory):
    return make_run_folder(tmp_path_factory.mktemp("integrity") / "runs" / "r1")


def _copy(sealed, tmp_path, name="r"):
    import shutil

    run = tmp_path / "runs" / name
    shutil.copytree(sealed, run)
    return run


def _edit(run, change, *, reseal=False):
    path = run / "calibration.json"
    d = json.loads(path.read_text(encoding="utf-8"))
    change(d)
    path.write_text(json.dumps(with_integrity(d) if reseal else d, indent=1), encoding="utf-8")


def _refused_everywhere(run, tmp_path, capsys, needle):
    cases = [
        ["certificate", str(run)],
        ["correct", str(run / "calibration.json"), str(run), "--out", str(tmp_path / "c.npy")],
        ["registry", "add", str(run), "--registry", f"sqlite:///{tmp_path / 'reg.sqlite'}"],
    ]
    for argv in cases:
        capsys.readouterr()
        assert main(argv) == 2, argv
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and needle in err[0] and "re-identify the run from its recording" in err[0], (argv, err)
    assert not (run / "certificate.pdf").exists() and not (tmp_path / "c.npy").exists()


def test_two_edited_values_are_refused_by_certificate_correct_and_registry_add(sealed, tmp_path, capsys):
    run = _copy(sealed, tmp_path)

    def change(d):
        d["parameters"]["b_x"]["value"] *= 0.5
        d["parameters"]["S_y"]["value"] = 0.0

    _edit(run, change)
    _refused_everywhere(run, tmp_path, capsys, "do not match its integrity digest")


def test_a_file_without_its_digest_is_refused(sealed, tmp_path, capsys):
    run = _copy(sealed, tmp_path)
    _edit(run, lambda d: d.pop("integrity"))
    _refused_everywhere(run, tmp_path, capsys, "has no integrity digest")


@pytest.mark.parametrize(("name", "value", "needle"), [
    ("S_x", -1.0, "physically implausible"),
    ("S_x", 1e300, "physically implausible"),
    ("b_x", 0.05, "prior σ"),
])  # fmt: skip
def test_absurd_values_are_refused_even_with_a_recomputed_digest(sealed, tmp_path, capsys, name, value, needle):
    run = _copy(sealed, tmp_path, name)

    def change(d):
        d["parameters"][name]["value"] = value

    _edit(run, change, reseal=True)
    _refused_everywhere(run, tmp_path, capsys, needle)


def test_an_untouched_file_is_accepted_whatever_its_layout_and_the_registry_keeps_its_digest(sealed, tmp_path):
    run = _copy(sealed, tmp_path)
    path = run / "calibration.json"
    d = json.loads(path.read_text(encoding="utf-8"))
    path.write_text(json.dumps(dict(reversed(list(d.items()))), indent=4, sort_keys=False), encoding="utf-8")
    result, digest = load_verified(path)
    assert digest == d["integrity"]["values_sha256"] and d["integrity"]["recording_sha256"] == result.recording_sha256
    reg = Registry(f"sqlite:///{tmp_path / 'reg.sqlite'}")
    assert main(["registry", "add", str(run), "--registry", reg.url]) == 0
    assert history(reg, "SIM-U-0001")[0].digest == digest


def test_save_writes_a_digest_that_load_verified_accepts_and_any_change_breaks(sealed, tmp_path):
    result = CalibrationResult.load(sealed / "calibration.json")
    out = result.save(tmp_path / "calibration.json")
    written, digest = load_verified(out)
    assert np.array_equal(written.x, result.x) and len(digest) == 64
    text = out.read_text(encoding="utf-8")
    d = json.loads(text)
    d["covariance"][0][0] *= 1.0000001
    out.write_text(json.dumps(d), encoding="utf-8")
    with pytest.raises(CalibrationTamperedError, match="do not match"):
        load_verified(out)

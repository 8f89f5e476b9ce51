"""Issue 18 item 9: the run's closing lines explain an INCONCLUSIVE certificate; ``correct RUN`` says what it gives."""

from __future__ import annotations

import json

import numpy as np

from benches.cli import main
from benches.session import verdict_explanation
from tests.certificate_fixtures import make_run_folder


def _cert(tmp_path, verdicts: dict[str, tuple[str, float | None]]):
    p = tmp_path / "certificate.json"
    p.write_text(json.dumps({"parameters": {n: {"verdict": v, "limit": lim} for n, (v, lim) in verdicts.items()}}))
    return p


def test_inconclusive_certificate_is_explained_in_plain_words_with_the_procedure_that_can(tmp_path):
    js = _cert(tmp_path, {"b_x": ("PASS", 1e-2), "r_x": ("NOT EVALUATED", 0.06), "r_y": ("NOT EVALUATED", 0.06)})
    lines = verdict_explanation(js, "INCONCLUSIVE")
    text = "\n".join(lines)
    assert "not a failure" in text and "r_x, r_y" in text and "size effect" in text and "1.6 °/s" in text
    assert "tablebench run --procedure ten-step-fast-spin" in text
    assert verdict_explanation(js, "PASS") == []
    und = verdict_explanation(_cert(tmp_path, {"S_x": ("UNDECIDED", 1e-3)}), "INCONCLUSIVE")
    assert any("S_x" in ln and "straddles" in ln for ln in und) and not any("fast-spin" in ln for ln in und)


def test_correct_on_a_recording_says_it_returns_hold_and_spin_samples_and_gives_their_times(tmp_path, capsys):
    run = make_run_folder(tmp_path / "run")
    out = tmp_path / "corrected.npy"
    assert main(["correct", str(run / "calibration.json"), str(run), "--out", str(out)]) == 0
    err = capsys.readouterr().err
    assert "returns only the samples of the" in err and "hold/spin acquisition windows" in err
    f = np.load(out)
    t = np.load(tmp_path / "corrected_time.npy")
    assert t.shape == (f.shape[0],) and np.all(np.diff(t) > 0)
    assert err.count(" s  (") >= 2  # one line per window with its bench times

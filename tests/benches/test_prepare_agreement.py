"""Issue 12 item 9 / issue 18 item 7: check, plan and run share ONE prepare step and agree on every input."""

from __future__ import annotations

import pytest

from benches.cli import main


def _proc(tmp_path, hold_s: float):
    p = tmp_path / f"p{hold_s:g}.yaml"
    p.write_text(
        "name: tiny\nversion: 1\nsteps:\n"
        "  - orient: {x: East, y: North, z: Up}\n  - hold: {name: h, duration_s: " + repr(hold_s) + "}\n",
        encoding="utf-8",
    )
    return p


@pytest.mark.parametrize("hold_s", [0.0004, 0.002])
def test_check_plan_and_run_accept_and_reject_the_same_hold(tmp_path, capsys, hold_s):
    proc = _proc(tmp_path, hold_s)
    rc_check = main(["check", str(proc), "--bench", "sim", "--quiet"])
    rc_plan = main(["plan", "--procedure", str(proc), "--bench", "sim"])
    out = tmp_path / "run"
    rc_run = main(["run", "--procedure", str(proc), "--bench", "sim", "--out", str(out), "--no-identify", "--plain"])
    err = capsys.readouterr().err
    if hold_s * 1000.0 < 1.0:  # shorter than one sample at 1 kHz: every command refuses it, with one line
        assert (rc_check, rc_plan, rc_run) == (2, 2, 2), err
        assert err.count("shorter than one sample") == 3
        assert not (out / "recording.h5").exists()
    else:
        assert rc_check == 0 and rc_run == 0
        assert rc_plan in (0, 2)  # a single hold identifies nothing; plan may say so, but not for the duration
        assert "shorter than one sample" not in err

"""``tablebench chamber`` on the simulated thermal bench in every dialect, and its bad input (exit 2, one line,
nothing sent); the bench file's chamber: section errors name the line."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from benches.bench_config import load_bench_text
from benches.cli.main import main
from core.yaml_source import ConfigError
from tests import REPO_ROOT

SIM_THERMAL = REPO_ROOT / "benches" / "sim-thermal.yaml"


def variant(tmp_path: Path, dialect: str) -> Path:
    text = SIM_THERMAL.read_text(encoding="utf-8").replace("dialect: espec", f"dialect: {dialect}")
    p = tmp_path / f"{dialect}.yaml"
    p.write_text(text, encoding="utf-8")
    return p


@pytest.mark.parametrize("dialect", ["espec", "watlow_f4", "watlow_f4t", "simserv"])
def test_status_set_stop_in_every_dialect(tmp_path, capsys, dialect):
    bench = str(variant(tmp_path, dialect))
    assert main(["chamber", "--bench", bench, "status"]) == 0
    assert re.search(r"air 2[23]\.\d\d °C, set point 23\.00 °C", capsys.readouterr().out)  # the lab's 23 °C ± noise
    assert main(["chamber", "--bench", bench, "set", "-20"]) == 0
    assert "set point -20.00 °C (read back)" in capsys.readouterr().out
    assert main(["chamber", "--bench", bench, "stop"]) == 0
    assert "safe set point 25" in capsys.readouterr().out


def test_bad_input_exits_2_with_one_line(capsys):
    assert main(["chamber", "--bench", str(SIM_THERMAL), "set", "120"]) == 2
    err = capsys.readouterr().err
    assert "outside the bench's set-point limits [-40, 85]" in err and "nothing was sent" in err
    assert main(["chamber", "--bench", str(SIM_THERMAL), "set"]) == 2
    assert main(["chamber", "--bench", str(REPO_ROOT / "benches" / "sim.yaml"), "status"]) == 2
    assert "has no chamber: section" in capsys.readouterr().err


@pytest.mark.parametrize(
    ("section", "message"),
    [
        ("chamber:\n  dialect: foo\n  driver: sim\n", "'foo' is not allowed"),
        ("chamber:\n  dialect: espec\n  driver: sim\n  setpoint_min_c: 50\n  setpoint_max_c: 40\n", "must be above"),
        ("chamber:\n  dialect: espec\n  driver: sim\n  options: {loop: 2}\n", "unknown key 'loop'"),
        ("chamber:\n  dialect: simserv\n  driver: sim\n  modbus: {address: 2}\n", "watlow dialects only"),
        ("chamber:\n  dialect: espec\n  driver: real\n  link: {kind: tcp, address: h}\n", "needs driver: sim"),
    ],
)
def test_chamber_section_errors_name_the_line(section, message):
    base = (REPO_ROOT / "benches" / "sim.yaml").read_text(encoding="utf-8")
    with pytest.raises(ConfigError, match=message) as e:
        load_bench_text(base + "\n" + section, "b.yaml")
    assert "b.yaml:" in str(e.value)

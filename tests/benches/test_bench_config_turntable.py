"""Bench-file keys of the turntable link: ACUTROL (resource, acl open points) and Modbus (watchdog)."""

from __future__ import annotations

import pytest

from benches.bench_config import load_bench_text
from core.yaml_source import ConfigError
from tests import REPO_ROOT

REAL = (REPO_ROOT / "benches" / "example-real.yaml").read_text(encoding="utf-8")
MODBUS = (REPO_ROOT / "benches" / "example-modbus.yaml").read_text(encoding="utf-8")
SIM = (REPO_ROOT / "benches" / "sim.yaml").read_text(encoding="utf-8")
RES = '  resource: "TCPIP0::192.168.53.1::9878::SOCKET"'


def test_acl_defaults_follow_the_spec_and_the_resource():
    text = REAL.split("  acl:")[0] + "  axes:" + REAL.split("\n  axes:", 1)[1]
    b = load_bench_text(text, "r.yaml")
    acl = b.turntable.acl
    assert acl is not None and acl.reply_profile == "tcp" and acl.mode_reply == "letter" and acl.decimals == 4
    assert acl.axes == (1, 2, 3) and acl.full_scale_deg == 360 and acl.time_variable is None
    assert not acl.open_interlocks_at_end and b.turntable.watchdog is None
    gpib = load_bench_text(text.replace(RES.split("#")[0].rstrip(), '  resource: "GPIB0::1::INSTR"'), "g.yaml")
    assert gpib.turntable.acl.reply_profile == "gpib"  # type: ignore[union-attr]


@pytest.mark.parametrize(
    ("old", "new", "words"),
    [
        ("    axes: {outer: 1, middle: 2, inner: 3}", "    axes: {outer: 1, middle: 1, inner: 3}", "three different"),
        ("    decimals: 4", "    decimals: 4\n    colour: red", "unknown key"),
        ("    mode_reply: letter", "    mode_reply: shout", "letter, word"),
        ("    full_scale_deg: 360", "    full_scale_deg: 300", "outside the controller's full-scale range ±150°"),
        ("    open_interlocks_at_end: true", "    open_interlocks_at_end: maybe", "true or false"),
        ("  attitude_accuracy_arcsec: 2.0", "  attitude_accuracy_arcsec: 2.0\n  watchdog_s: 2", "no host heartbeat"),
        ("  driver: acutrol", "  driver: ascii-serial", "sim, acutrol, modbus-tcp"),
    ],
)
def test_acl_mistakes_name_the_key(old, new, words):
    assert old in REAL
    with pytest.raises(ConfigError, match="turntable") as e:
        load_bench_text(REAL.replace(old, new, 1), "r.yaml")
    assert words in str(e.value)


def test_resource_rules():
    no_res = "\n".join(line for line in REAL.splitlines() if not line.startswith("  resource:"))
    with pytest.raises(ConfigError, match="resource: is required for driver 'acutrol'.*GPIB0::1::INSTR"):
        load_bench_text(no_res, "r.yaml")
    with pytest.raises(ConfigError, match="resource: is only for driver 'acutrol'"):
        load_bench_text(MODBUS.replace("  float_word_order: big", RES + "\n  float_word_order: big"), "m.yaml")
    with pytest.raises(ConfigError, match="acl: is only for an ACUTROL table"):
        load_bench_text(
            MODBUS.replace("  float_word_order: big", "  acl: {decimals: 3}\n  float_word_order: big"), "m.yaml"
        )


def test_modbus_watchdog_rule_and_simulated_controller_choice():
    with pytest.raises(ConfigError, match="shorter than watchdog_s"):
        load_bench_text(MODBUS.replace("  watchdog_s: 2.0", "  watchdog_s: 0.3"), "m.yaml")
    b = load_bench_text(SIM, "s.yaml")
    assert b.turntable.sim_controller == "acutrol" and b.simulation.table.watchdog is None  # type: ignore[union-attr]
    with pytest.raises(ConfigError, match="acutrol, modbus"):
        load_bench_text(SIM.replace("  controller: acutrol", "  controller: gpib"), "s.yaml")
    acl_part = SIM[SIM.index("  acl:") : SIM.index("  axes:")]
    modbus_sim = SIM.replace("  controller: acutrol", "  controller: modbus").replace(acl_part, "  watchdog_s: 2.0\n")
    b = load_bench_text(modbus_sim, "s.yaml")
    assert b.turntable.acl is None and b.simulation.table.watchdog == 2.0  # type: ignore[union-attr]


def test_modbus_map_named_by_the_bench(tmp_path):
    plc = REPO_ROOT / "tests" / "data" / "plc_table_map.yaml"
    text = MODBUS.replace("  float_word_order: big\n", f"  modbus_map: {plc}\n")
    b = load_bench_text(text, tmp_path / "m.yaml")
    assert b.turntable.modbus_map.name == "test PLC table" and b.turntable.float_word_order is None
    (tmp_path / "maps").mkdir()
    (tmp_path / "maps" / "plc.yaml").write_text(plc.read_text(encoding="utf-8"), encoding="utf-8")
    rel = load_bench_text(
        MODBUS.replace("  float_word_order: big\n", "  modbus_map: maps/plc.yaml\n"), tmp_path / "m.yaml"
    )
    assert rel.turntable.modbus_map.state["status"] == 100  # relative to the bench file
    with pytest.raises(ConfigError, match="modbus_map: register map file .* not found"):
        load_bench_text(MODBUS.replace("  float_word_order: big\n", "  modbus_map: nope.yaml\n"), tmp_path / "m.yaml")
    with pytest.raises(ConfigError, match="modbus_map: is only for a Modbus table"):
        load_bench_text(REAL.replace("  rate_tolerance_dps: 0.01", f"  modbus_map: {plc}"), tmp_path / "r.yaml")


def test_simulated_plc_table_over_loopback(tmp_path):
    from benches.factory import open_bench

    plc = REPO_ROOT / "tests" / "data" / "plc_table_map.yaml"
    acl_part = SIM[SIM.index("  acl:") : SIM.index("  axes:")]
    text = SIM.replace("  controller: acutrol", "  controller: modbus").replace(
        acl_part, f"  watchdog_s: 2.0\n  modbus_map: {plc}\n"
    )
    cfg = load_bench_text(text, tmp_path / "s.yaml")
    with open_bench(cfg, seed=1, transport="loopback") as bench:
        assert bench.turntable.map.name == "test PLC table"
        bench.turntable.move_to([0.3, -0.2, 0.1])
        for _ in range(20):
            bench.unit.read(200)
            bench.turntable.heartbeat()
        s = bench.turntable.read_state()
        assert s.status & 1 and abs(s.angles[0] - 0.3) < 1e-4

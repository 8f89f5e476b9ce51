"""Bench YAML loading: shipped benches, SI conversion, and file:line errors for bad input."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from analysis.earth import normal_gravity
from analysis.units import ARCSEC, DEG, DEG_PER_HOUR, MM, PPM, UG
from benches.bench_config import load_bench, load_bench_text
from core.yaml_source import ConfigError
from drivers.sim.world import SimulatedWorld
from tests import REPO_ROOT, line_of

BENCHES = REPO_ROOT / "benches"
SIM = (BENCHES / "sim.yaml").read_text(encoding="utf-8")


@pytest.mark.parametrize("name", ["sim.yaml", "sim-gyro-noise.yaml", "example-real.yaml"])
def test_shipped_benches_load(name: str) -> None:
    b = load_bench(BENCHES / name)
    assert b.path == BENCHES / name and b.text.startswith("#")
    assert len(b.turntable.limits) == 3 and b.unit.sample_rate > 0
    assert (b.simulation is not None) == (name != "example-real.yaml")
    if b.simulation is not None:
        w = SimulatedWorld.from_bench(b)
        assert w.sample_rate == b.unit.sample_rate and len(w.produce(10)) == 10


def test_sim_bench_values_in_si() -> None:
    b = load_bench(BENCHES / "sim.yaml")
    assert b.site.latitude == pytest.approx(48.15 * DEG)
    assert b.site.g == pytest.approx(normal_gravity(48.15 * DEG, 520.0)) and b.site.g_source.startswith("WGS-84")
    lim = b.turntable.limits[0]
    assert lim.rate_max == pytest.approx(300 * DEG) and lim.position_min is None
    assert b.turntable.position_tolerance == pytest.approx(2 * ARCSEC)
    s = b.simulation
    assert s is not None and s.seed == 20261122 and s.transport == "in-process"
    assert s.accel.bias[0] == pytest.approx(100 * UG) and s.accel.scale[0] == pytest.approx(200 * PPM)
    assert s.accel.lever_arms[1][1] == pytest.approx(-28 * MM)
    assert s.gyro.bias[0] == pytest.approx(0.5 * DEG_PER_HOUR)
    truth = SimulatedWorld.from_bench(b).truth()
    # r as the model identifies it: −(1 + S_y) ρ_yy − ½ (τ_yx ρ_yx + τ_yz ρ_yz) (sim.yaml: S_y −150 ppm,
    # τ_yx 20″, τ_yz 35″, ρ_y = [5, −28, 6] mm)
    r_y = (1 - 150 * PPM) * 28 * MM - 0.5 * (20 * ARCSEC * 5 * MM + 35 * ARCSEC * 6 * MM)
    assert truth["r_y"] == pytest.approx(r_y, rel=1e-12) and truth["tau_xy"] == pytest.approx(30 * ARCSEC)
    assert set(b.unit.prior) == set(truth)
    # every parameter has a limit but the gyro's g-sensitivity, which 60 s holds cannot resolve (no conformity)
    assert set(truth) - set(b.limits) == {f"gyro_G_{i}{j}" for i in "xyz" for j in "xyz"}
    for name, v in truth.items():  # the shipped truth passes its own limits, the prior covers it
        assert abs(v) < b.limits.get(name, np.inf) and abs(v) < 3 * b.unit.prior[name]


def test_real_bench_measured_g_and_addresses() -> None:
    b = load_bench(BENCHES / "example-real.yaml")
    assert b.site.g == 9.81274 and b.site.g_source == "measured"
    assert b.turntable.driver == "acutrol" and b.turntable.resource == "TCPIP0::192.168.53.1::9878::SOCKET"
    assert b.unit.driver == "serial" and b.unit.address == "/dev/ttyUSB0"
    assert b.turntable.limits[2].position_max == pytest.approx(170 * DEG)


def test_gyro_noise_bench_has_periodic_and_arma_on_gyros() -> None:
    s = load_bench(BENCHES / "sim-gyro-noise.yaml").simulation
    assert s is not None and s.periodic and s.arma
    assert all(p.channel.startswith("gyro") for p in s.periodic + s.arma)  # type: ignore[operator]
    assert s.periodic[0].amplitude == pytest.approx(0.6 * DEG)


def test_prior_group_and_single_override_and_sci_notation() -> None:
    text = SIM.replace("    bias_ug: 300.0\n", "    bias_ug: 300.0\n    b_z_ug: 5e2\n", 1)
    b = load_bench_text(text, "x.yaml")
    assert b.unit.prior["b_x"] == pytest.approx(300 * UG) and b.unit.prior["b_z"] == pytest.approx(500 * UG)


@pytest.mark.parametrize(
    ("old", "new", "needle", "words"),
    [
        ("latitude_deg: 48.15", "latitude_deg: north", "latitude_deg", ["site.latitude_deg", "expected a number"]),
        ("latitude_deg: 48.15", "latitude_deg: 98.15", "latitude_deg", ["out of range", "[-90, 90]"]),
        ("  attitude_accuracy_arcsec: 1.0", "  attitude_accuracy_arcsec: 1.0\n  colour: red", "colour", ["unknown"]),
        ("sample_rate_hz: 1000.0", "sample_rate_hz: [1000]", "sample_rate_hz", ["unit.sample_rate_hz"]),
        ("    bias_ug: [100.0, -80.0, 120.0]", "    bias_ug: [100.0, -80.0]", "bias_ug: [100.0, -80.0]", ["list of 3"]),
        ("  transport: in-process", "  transport: carrier-pigeon", "transport", ["in-process, loopback"]),
        (
            "inner:  {rate_max_dps: 400.0,",
            "inner:  {rate_max_dps: -4,",
            "inner:",
            ["turntable.axes.inner.rate_max_dps"],
        ),
        ("  driver: sim\n  model: SIM-3AX", "  driver: modbus\n  model: SIM-3AX", "driver: modbus", ["modbus-tcp"]),
        ("  rate_tolerance_dps: 0.01", "  rate_tolerance_dps: 0.01\n  watchdog_s: 2", "watchdog_s", ["no host"]),
        (
            "  seed: 20261122",
            "  seed: 20261122\n  arma:\n    - {channel: gyro_x, phi: [1.2], sigma_dph: 1}",
            "phi",
            ["stationary"],
        ),
        (
            "  seed: 20261122",
            "  seed: 20261122\n  periodic:\n    - {channel: gyro_q, frequency_hz: 5, amplitude_dps: 1}",
            "gyro_q",
            ["gyro_x"],
        ),
        (
            "  seed: 20261122",
            "  seed: 20261122\n  periodic:\n    - {channel: accel_x, frequency_hz: 5, amplitude_dps: 1}",
            "accel_x",
            ["amplitude_ug"],
        ),
        (
            "mounting: [[1, 0, 0], [0, 1, 0], [0, 0, 1]]",
            "mounting: [[1, 0, 0], [0, 1, 0], [0, 0, 2]]",
            "mounting",
            ["rotation"],
        ),
    ],
)
def test_bad_values_name_file_line_and_fix(old: str, new: str, needle: str, words: list[str]) -> None:
    assert old in SIM
    text = SIM.replace(old, new, 1)
    with pytest.raises(ConfigError) as exc:
        load_bench_text(text, "benches/bad.yaml")
    msg = str(exc.value)
    assert msg.startswith(f"benches/bad.yaml:{line_of(text, needle)}:"), msg
    for w in words:
        assert w in msg, msg


def test_yaml_syntax_error_and_missing_file(tmp_path: Path) -> None:
    p = tmp_path / "broken.yaml"
    p.write_text(SIM.replace("  latitude_deg: 48.15", "  latitude_deg: [48.15"), encoding="utf-8")
    with pytest.raises(ConfigError, match=r"broken\.yaml:\d+: YAML syntax error"):
        load_bench(p)
    with pytest.raises(ConfigError, match="file not found"):
        load_bench(tmp_path / "nope.yaml")
    with pytest.raises(ConfigError, match="empty"):
        load_bench_text("", "e.yaml")


def test_simulation_section_rules() -> None:
    no_sim = SIM.split("simulation:")[0]
    with pytest.raises(ConfigError, match="simulation: is required"):
        load_bench_text(no_sim, "s.yaml")
    real = (BENCHES / "example-real.yaml").read_text(encoding="utf-8") + "simulation:\n  seed: 1\n"
    with pytest.raises(ConfigError, match="only allowed"):
        load_bench_text(real, "r.yaml")


def test_defaults_when_simulation_noise_omitted() -> None:
    text = SIM.split("  accel_noise:")[0] + "  anti_alias_hz: 0\n"
    b = load_bench_text(text, "d.yaml")
    assert b.simulation is not None
    np.testing.assert_allclose(b.simulation.accel_noise.white, b.unit.noise.vrw)
    assert b.simulation.anti_alias_hz is None and math.isclose(b.simulation.table.overshoot, 5 * ARCSEC)


def test_reference_standards_are_validated() -> None:
    text = (BENCHES / "sim.yaml").read_text(encoding="utf-8")
    good = text + (
        "reference_standards:\n"
        "  - {name: angle encoders, serial_number: E1, certificate: C-1, calibrated_by: Lab, due: 2027-03-01}\n"
    )
    cfg = load_bench_text(good, "good.yaml")
    assert cfg.reference_standards[0].due.isoformat() == "2027-03-01"
    bad = text + "reference_standards:\n  - {name: encoders, certificate: C-1, due: next spring}\n"
    with pytest.raises(ConfigError, match="due.*YYYY-MM-DD"):
        load_bench_text(bad, "bad.yaml")
    missing = text + "reference_standards:\n  - {name: encoders, due: 2027-03-01}\n"
    with pytest.raises(ConfigError, match="certificate"):
        load_bench_text(missing, "missing.yaml")

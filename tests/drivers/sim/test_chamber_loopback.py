"""The simulated chamber in the one simulated world, served on loopback in each dialect, driven by the real
drivers through a soak; and its physics against closed forms (step overshoot, first-order lag)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from analysis.thermal.soak import SoakCriterion, SoakMonitor
from analysis.units import celsius_to_kelvin as C
from drivers.chamber.base import ChamberError, ChamberSettings
from drivers.chamber.config import ChamberConfig, ChamberLink
from drivers.chamber.connect import open_chamber
from drivers.chamber.espec import EspecSettings
from drivers.chamber.safety import leave_safe
from drivers.chamber.simserv import SimservSettings
from drivers.chamber.watlow import WatlowF4TSettings
from drivers.sim.chamber_servers import EspecServer, SimservServer, WatlowServer
from drivers.sim.config import SimConfig
from drivers.sim.thermal_config import ChamberSim, ThermalTruth, TriadThermal
from drivers.sim.world import SimulatedWorld

FS = 20.0


def world(chamber: ChamberSim | None = None, thermal: ThermalTruth | None = None, seed: int = 3) -> SimulatedWorld:
    return SimulatedWorld(SimConfig(sample_rate=FS, chamber=chamber or ChamberSim(), thermal=thermal), seed)


def unit_temperature(w: SimulatedWorld, seconds: float) -> tuple[np.ndarray, np.ndarray]:
    """Advance the world by reading the unit's frames; (times, temperature K) from its temperature channel."""
    n = int(round(seconds * FS))
    k0 = w.samples_produced
    fr = w.produce(n)
    t = (k0 + np.arange(n)) / FS
    return t, fr.temperature.astype(float) * w.scale.temperature_lsb + 273.15


def test_air_step_overshoot_matches_the_second_order_closed_form():
    zeta = 0.7
    w = world(ChamberSim(ramp_up=1e3, ramp_down=1e3, air_noise=0.0, air_damping=zeta))
    w.chamber_run(True)
    w.chamber_setpoint(C(43.0))
    peak = -np.inf
    for _ in range(900):
        w.produce(int(FS))
        peak = max(peak, w.chamber_truth()[0])
    expected = math.exp(-math.pi * zeta / math.sqrt(1 - zeta**2))
    assert (peak - C(43.0)) / 20.0 == pytest.approx(expected, rel=0.02)


def test_unit_lags_the_air_first_order():
    tau = 600.0
    w = world(ChamberSim(ramp_up=1e3, ramp_down=1e3, air_noise=0.0, air_time_constant=0.5, unit_time_constant=tau))
    w.chamber_run(True)
    w.chamber_setpoint(C(43.0))
    w.produce(int(1200 * FS))
    _, unit, rate = w.chamber_truth()
    assert unit == pytest.approx(C(43.0) - 20.0 * math.exp(-1200 / tau), abs=0.05)
    assert rate == pytest.approx(20.0 / tau * math.exp(-1200 / tau), rel=0.02)


def test_ramp_rate_limit_of_the_set_point_path():
    w = world(ChamberSim(air_noise=0.0, air_time_constant=1.0, ramp_down=1.0 / 60))
    w.chamber_run(True)
    w.chamber_setpoint(C(3.0))
    w.produce(int(600 * FS))
    assert w.chamber_truth()[0] == pytest.approx(C(23.0 - 10.0), abs=0.1)  # 10 min at 1 K/min


def test_unit_truth_follows_its_own_temperature():
    b1 = 2e-4  # m/s² per K on every accelerometer
    thermal = ThermalTruth(accel=TriadThermal(bias=((b1, b1, b1),)))
    w = world(ChamberSim(ramp_up=1e3, ramp_down=1e3, air_noise=0.0, air_time_constant=0.5), thermal)
    ref = world(ChamberSim(), None)
    w.chamber_run(True)
    w.chamber_setpoint(C(43.0))
    w.produce(int(3000 * FS))
    ref.produce(int(3000 * FS))
    fr, fr0 = w.produce(200), ref.produce(200)
    _, unit, _ = w.chamber_truth()
    lsb = w.scale.accel_lsb
    delta = (fr.counts[:, 2].mean() - fr0.counts[:, 2].mean()) * lsb
    assert delta == pytest.approx(b1 * (unit - C(23.0)), rel=0.01)


def soak_over_the_wire(w: SimulatedWorld, chamber, target_c: float) -> SoakMonitor:
    chamber.start()
    assert chamber.set_setpoint(C(target_c)) == pytest.approx(C(target_c))
    crit = SoakCriterion(tolerance=0.5, rate_limit=0.1 / 60, dwell=600.0, timeout=3 * 3600.0)
    mon = SoakMonitor(crit, C(target_c), w.time)
    while not mon.settled:
        assert not mon.timed_out, mon.status()
        t, temp = unit_temperature(w, 30.0)
        mon.feed(t, temp)
        r = chamber.read()
        assert r.setpoint == pytest.approx(C(target_c)) and r.alarm is False
    return mon


DIALECTS = ["watlow_f4_rtu", "watlow_f4_tcp", "watlow_f4t", "espec", "simserv"]


def serve(w: SimulatedWorld, dialect: str):
    s = ChamberSettings(setpoint_min=C(-30.0), setpoint_max=C(70.0), timeout=2.0)
    if dialect.startswith("watlow_f4_"):
        framing = dialect.rsplit("_", 1)[1]
        srv = WatlowServer(w, "f4", framing)
        cfg = ChamberConfig("watlow_f4", ChamberLink("tcp", "127.0.0.1", srv.port, framing=framing, send_delay=0.0), s)
    elif dialect == "watlow_f4t":
        srv = WatlowServer(w, "f4t", "tcp", word_order="high_first")
        cfg = ChamberConfig(
            "watlow_f4t", ChamberLink("tcp", "127.0.0.1", srv.port), s, WatlowF4TSettings(word_order="high_first")
        )
    elif dialect == "espec":
        srv = EspecServer(w, mon_humidity="absent")
        cfg = ChamberConfig("espec", ChamberLink("tcp", "127.0.0.1", srv.port), s, EspecSettings())
    else:
        srv = SimservServer(w)
        cfg = ChamberConfig("simserv", ChamberLink("tcp", "127.0.0.1", srv.port), s, SimservSettings(run_pause=0.0))
    return srv, open_chamber(cfg)


@pytest.mark.parametrize("dialect", DIALECTS)
def test_loopback_soak_and_safe_exit(dialect):
    w = world()
    srv, conn = serve(w, dialect)
    try:
        mon = soak_over_the_wire(w, conn.driver, -10.0)
        _, unit, rate = w.chamber_truth()
        assert abs(unit - C(-10.0)) <= 0.5 and abs(rate) <= 0.1 / 60
        # a 33 K step with τ_u = 10 min: ≥ ln(33/0.5)·τ_u ≈ 42 min of lag, plus the dwell
        assert mon.settled_at - mon.start > math.log(33 / 0.5) * 600.0
        assert leave_safe(conn.driver) == []
        sp, _, running, _ = w.chamber_reading()
        assert sp == pytest.approx(C(25.0)) and (running is False or dialect.startswith("watlow"))
    finally:
        conn.close()
        srv.close()


@pytest.mark.parametrize("dialect", ["watlow_f4_rtu", "espec", "simserv"])
def test_loopback_refusal_of_a_set_point_outside_the_controller_range(dialect):
    w = world(ChamberSim(setpoint_min=C(-20.0)))
    srv, conn = serve(w, dialect)
    try:
        with pytest.raises(ChamberError):
            conn.driver.set_setpoint(C(-25.0))  # inside the bench limits, outside the controller's range
    finally:
        conn.close()
        srv.close()


def test_loopback_alarm_is_reported():
    w = world()
    srv, conn = serve(w, "simserv")
    try:
        w.chamber.alarm = True
        assert conn.driver.read().alarm is True
    finally:
        conn.close()
        srv.close()

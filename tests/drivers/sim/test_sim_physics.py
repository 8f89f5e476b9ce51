"""Physics of the simulated unit: gravity at rest, Earth rate, lever-arm centripetal terms, error model."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from analysis import gimbal
from analysis.earth import EARTH_RATE, normal_gravity
from analysis.units import DEG, MM, UG
from drivers.imu_unit.counts import frames_to_block
from drivers.sim.config import AccelTruth, NoiseTruth, SimConfig, TableModel, example_navigation_grade
from drivers.sim.inprocess import SimInertialUnit, SimTurntable
from drivers.sim.world import SimulatedWorld


def _settle(world: SimulatedWorld, angles: list[float], max_s: float = 60.0) -> None:
    table = SimTurntable(world)
    table.move_to(angles)
    for _ in range(int(max_s * 10)):
        world.produce(int(world.sample_rate / 10))
        table.heartbeat()
        st = table.read_state()
        if st.status & st.status.IN_POSITION:
            world.produce(int(world.sample_rate))  # let the arcsec-level settling transient die out
            return
    raise AssertionError("table never reached IN_POSITION")


def _read(unit: SimInertialUnit, table: SimTurntable, n: int, block: int = 200) -> np.ndarray:
    """Read n samples in blocks, feeding the watchdog like the runner does; returns accel (n, 3)."""
    parts = []
    while n > 0:
        b = unit.read(min(block, n))
        table.heartbeat()
        parts.append(np.hstack([b.accel, b.gyro]))
        n -= min(block, n)
    return np.vstack(parts)


def test_static_hold_reproduces_wgs84_gravity_and_earth_rate() -> None:
    cfg = SimConfig(latitude=37.0 * DEG, height=1200.0)  # perfect, noiseless unit
    w = SimulatedWorld(cfg, seed=1)
    angles = [0.7, -0.4, 1.1]
    _settle(w, angles)
    blk = frames_to_block(w.produce(2000), w.scale)
    g_ref = normal_gravity(37.0 * DEG, 1200.0)
    f = blk.accel.mean(0)
    # magnitude: WGS-84 normal gravity at the site, to the count quantisation (0.1 µg)
    assert abs(np.linalg.norm(f) - g_ref) < 0.2 * UG
    # direction: C_n^b [0, 0, g] from an independent scipy rotation
    from scipy.spatial.transform import Rotation

    c_bn = Rotation.from_euler("ZXY", angles).as_matrix()
    np.testing.assert_allclose(f, c_bn.T @ np.array([0, 0, g_ref]), atol=0.2 * UG)
    # gyro: Earth rate in the body frame
    om = blk.gyro.mean(0)
    om_ref = c_bn.T @ np.array([0.0, EARTH_RATE * math.cos(37 * DEG), EARTH_RATE * math.sin(37 * DEG)])
    np.testing.assert_allclose(om, om_ref, atol=1e-3 * EARTH_RATE)


def test_static_hold_matches_error_model() -> None:
    base = example_navigation_grade()
    cfg = replace(base, accel_noise=NoiseTruth(white=(15 * UG,) * 3))  # white noise only
    w = SimulatedWorld(cfg, seed=3)
    angles = [0.3, 0.9, -2.0]
    _settle(w, angles)
    n = 5000
    blk = frames_to_block(w.produce(n), w.scale)
    f0 = gimbal.gravity_in_body(np.array(angles), cfg.local_g)
    a = cfg.accel
    expected = np.empty(3)
    pairs = {(0, 1): 0, (0, 2): 1, (1, 0): 2, (1, 2): 3, (2, 0): 4, (2, 1): 5}
    for i in range(3):
        cross = sum(a.misalignment[pairs[(i, j)]] * f0[j] for j in range(3) if j != i)
        expected[i] = f0[i] * (1 + a.scale[i]) + cross + a.bias[i] + a.quadratic[i] * f0[i] ** 2
    sigma_mean = 15 * UG * math.sqrt(cfg.sample_rate) / math.sqrt(n)
    np.testing.assert_allclose(blk.accel.mean(0), expected, atol=5 * sigma_mean)
    # and the errors are really there (the test can fail): the error-free reading is far off
    assert np.max(np.abs(f0 - expected)) > 50 * sigma_mean


@pytest.mark.parametrize("rate_dps", [100.0, -60.0])
def test_spin_about_body_y_shows_lever_arm_centripetal_terms(rate_dps: float) -> None:
    rho = ((30 * MM, 4 * MM, -3 * MM), (5 * MM, -28 * MM, 6 * MM), (-4 * MM, 2 * MM, 32 * MM))
    cfg = SimConfig(accel=AccelTruth(lever_arms=rho), table=replace(TableModel(), rate_jitter=0.0))
    w = SimulatedWorld(cfg, seed=5)
    table, unit = SimTurntable(w), SimInertialUnit(w)
    omega = rate_dps * DEG
    table.spin(2, omega)  # inner gimbal = body y with identity mounting at zero angles
    while not table.read_state().status & table.read_state().status.AT_RATE:
        unit.read(10)
        table.heartbeat()
    n_rev = 2
    n = int(round(n_rev * 360.0 / abs(rate_dps) * cfg.sample_rate))
    data = _read(unit, table, n)
    f = data[:, :3].mean(0)  # gravity averages out over whole revolutions
    w2 = omega**2
    # x and z: −ω² ρ_ii (= r_i ω² with r_i = −ρ_ii); y (spin axis): no centripetal term
    assert f[0] == pytest.approx(-w2 * rho[0][0], rel=2e-3)
    assert f[2] == pytest.approx(-w2 * rho[2][2], rel=2e-3)
    assert abs(f[1]) < 1e-3 * w2 * 0.03
    # truth reports r_i = −ρ_ii
    tr = w.truth()
    assert tr["r_x"] == pytest.approx(-rho[0][0]) and tr["r_z"] == pytest.approx(-rho[2][2])
    # gyro sees the spin (+ Earth rate, which averages to its y component over whole turns)
    assert data[:, 4].mean() == pytest.approx(omega + EARTH_RATE * math.cos(cfg.latitude), rel=1e-6)


def test_angular_acceleration_term_during_ramp() -> None:
    """During a ramp about body y, accelerometer x at ρ_x = (0, 0, h) senses (ω̇ × ρ)_x = ω̇ h."""
    h = 50 * MM
    cfg = SimConfig(
        accel=AccelTruth(lever_arms=((0, 0, h), (0, 0, 0), (0, 0, 0))), table=replace(TableModel(), rate_jitter=0.0)
    )
    w = SimulatedWorld(cfg, seed=2)
    acc = cfg.table.limits[2].accel_max
    base = frames_to_block(w.produce(200), w.scale).accel[:, 0].mean()
    w.command_rate(2, 20 * DEG)  # ramp lasts 0.2 s at 100 °/s²
    blk = frames_to_block(w.produce(100), w.scale)
    # at small angles gravity barely changes x (γ ≤ 0.1°·...); centripetal ω² h along x is 0 (ρ ∥ z)
    ang = gimbal.gravity_in_body(
        np.stack([np.zeros(100), np.zeros(100), 0.5 * acc * (np.arange(100) / 1000) ** 2], 1), cfg.local_g
    )
    excess = blk.accel[:, 0] - (ang[:, 0] + base)
    assert np.mean(excess) == pytest.approx(acc * h, rel=1e-3)


def test_kinematics_against_gimbal_module_and_numerical_derivative() -> None:
    """ω from the (tilted-axes) general path equals analysis.gimbal at zero tilt; ω̇ equals dω/dt numerically."""
    rng = np.random.default_rng(0)
    ang = rng.uniform(-3, 3, (50, 3))
    rat = rng.uniform(-2, 2, (50, 3))
    acc = rng.uniform(-1, 1, (50, 3))
    w = SimulatedWorld(SimConfig(table=replace(TableModel(), non_orthogonality=(1e-15, 1e-15))), 0)
    c_bn, om, al = w._kinematics(ang, rat, acc)
    np.testing.assert_allclose(om, gimbal.table_rate(ang, rat), atol=1e-12)
    np.testing.assert_allclose(c_bn, gimbal.body_to_nav(ang), atol=1e-12)
    h = 1e-6
    num = (gimbal.table_rate(ang + rat * h + 0.5 * acc * h * h, rat + acc * h) - gimbal.table_rate(ang, rat)) / h
    np.testing.assert_allclose(al, num, atol=1e-5)
    # with tilts and wobble: ω^t from the closed form equals the one from C_t^n, [ω×] = Cᵀ dC/dt (numerically)
    tm = replace(TableModel(), non_orthogonality=(10 * 4.85e-6, -5 * 4.85e-6), wobble=20 * 4.85e-6)
    w2 = SimulatedWorld(SimConfig(table=tm), 0)
    c0, om2, _ = w2._kinematics(ang, rat, acc)
    c1, _, _ = w2._kinematics(ang + rat * h, rat, acc)
    c_m, _, _ = w2._kinematics(ang - rat * h, rat, acc)
    skew = np.swapaxes(c0, 1, 2) @ (c1 - c_m) / (2 * h)
    om_num = np.stack([skew[:, 2, 1], skew[:, 0, 2], skew[:, 1, 0]], -1)
    np.testing.assert_allclose(om2, om_num, atol=1e-8)
    d = np.abs(om2 - om).max()
    assert 1e-6 < d < 5 * 20 * 4.85e-6 * np.abs(rat).max()


def test_wobble_and_non_orthogonality_tilt_the_unit() -> None:
    """Inner wobble w: at γ = 0 the unit is tilted by w about x, so y senses g·sin w; zero by default."""
    from analysis.units import ARCSEC

    wob = 20 * ARCSEC
    ref, tilted = (
        SimulatedWorld(SimConfig(table=replace(TableModel(), wobble=x, position_jitter=0.0)), 0) for x in (0.0, wob)
    )
    out = []
    for w in (ref, tilted):
        _settle(w, [0.0, 0.0, 2 * math.pi])  # one full inner turn back to γ = 0 (unwrapped 2π)
        out.append(frames_to_block(w.produce(500), w.scale).accel.mean(0))
    g = SimConfig().local_g
    assert out[0][1] == pytest.approx(0.0, abs=0.2 * UG)
    assert abs(out[1][1]) == pytest.approx(g * wob, rel=1e-3)


def test_table_turns_at_its_realised_rate_error_and_the_encoder_reports_that_motion() -> None:
    """A table with a rate error ε turns at (1 + ε) × its command (docs/methods/simulation.md): the true (encoder)
    angle advances at that rate, the reported rate is that measured rate, and the gyro senses it — so the
    encoder angle over time is the gyro's scale reference (a world that scaled only the reported rate fails)."""
    from drivers.sim.config import BudgetInputs, GyroTruth

    s_y = 300e-6
    cfg = SimConfig(
        table=replace(TableModel(), rate_jitter=0.0, position_jitter=0.0),
        gyro=GyroTruth(scale=(0.0, s_y, 0.0)),
        budget_inputs=BudgetInputs(rate_error_bound=0.02),
    )
    w = SimulatedWorld(cfg, seed=2)
    eps = float(w.truth_arrays()["table_rate_error"][2])
    assert abs(eps) > 2e-3  # a large realised error on the inner axis (the test needs one)
    table, unit = SimTurntable(w), SimInertialUnit(w)
    cmd = 60.0 * DEG
    table.spin(2, cmd)  # inner gimbal = body y at zero angles (identity mounting)
    _read(unit, table, int(2 * cfg.sample_rate))  # ramp (0.6 s at 100 °/s²) done, watchdog fed
    s0 = table.read_state()
    n_rev = 2
    n = int(round(n_rev * 2 * math.pi / (cmd * (1 + eps)) * cfg.sample_rate))  # whole turns at the true rate
    data = _read(unit, table, n)
    s1 = table.read_state()
    slope = (s1.angles[2] - s0.angles[2]) / (s1.time - s0.time)
    # the encoder angle advances at the realised rate, to the encoder's resolution (2π / 2²⁴ over 2 turns)
    assert slope == pytest.approx(cmd * (1 + eps), rel=1e-7)
    # the reported rate is the measured rate of that motion, not the command scaled after the fact
    assert s1.rates[2] == pytest.approx(slope, rel=1e-7)
    # the gyro senses the true motion: (1 + S_y) × the encoder rate (+ Earth rate's y part over whole turns)
    assert data[:, 4].mean() == pytest.approx((1 + s_y) * slope + EARTH_RATE * math.cos(cfg.latitude), rel=1e-6)
    # and the host's at-rate decision sees the table off its command by ε (what its tolerance must admit)
    assert abs(s1.rates[2] - cmd) == pytest.approx(abs(eps) * cmd, rel=1e-6)


def test_rate_jitter_is_real_motion_the_encoder_angle_integrates_it_and_a_move_absorbs_it() -> None:
    """The table's physical rate jitter is motion: the gyro senses it and the true (encoder) angle is its
    integral, so the angle over time of a spin is the gyro's mean rate to the encoder's resolution (a world whose
    angles ignored the jitter's integral is off by its random walk, σ √(2 τ_c T), here ~1e-4 of the rate). The next
    position command servoes the true angle: it ends on its target."""
    jit = 0.05 * DEG  # a large jitter: its random walk over the spin is ~1e-4 of the rate
    cfg = SimConfig(table=replace(TableModel(), rate_jitter=jit, position_jitter=0.0))
    w = SimulatedWorld(cfg, seed=3)
    table, unit = SimTurntable(w), SimInertialUnit(w)
    cmd = 60.0 * DEG
    table.spin(2, cmd)  # inner gimbal = body y at zero angles (identity mounting)
    _read(unit, table, int(2 * cfg.sample_rate))
    s0 = table.read_state()
    n = int(round(2 * 2 * math.pi / cmd * cfg.sample_rate))  # two turns
    data = _read(unit, table, n)
    s1 = table.read_state()
    slope = (s1.angles[2] - s0.angles[2]) / (s1.time - s0.time)
    mean_rate = data[:, 4].mean() - EARTH_RATE * math.cos(cfg.latitude)  # the perfect gyro: table rate + Earth's y
    jitter_mean = mean_rate - cmd
    assert abs(jitter_mean) > 1e-5 * cmd  # the jitter's mean over the spin is well above the test's tolerance
    assert slope == pytest.approx(mean_rate, rel=2e-7)  # the encoder's angle over time is the gyro's mean rate
    # after the spin a position command ends on its target: the servo absorbs the angle the jitter left
    table.stop()
    _read(unit, table, int(3 * cfg.sample_rate))
    target = [0.0, 0.0, 6 * math.pi]
    _settle(w, target)
    lsb = 2 * math.pi / 2**cfg.table.encoder_bits
    np.testing.assert_allclose(table.read_state().angles, target, atol=lsb)

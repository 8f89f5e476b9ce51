"""The gyro model and the whole-unit identification (accelerometer + gyro states from one record).

Independent references: the model's own forward equation written out here, imucal's Ferraris turntable
method (``imucal.FerrarisCalibration``, MIT; Ferraris et al. 1995) on noise-free data without Earth rate.
"""

from __future__ import annotations

import math

import numpy as np

from analysis import gimbal
from analysis.earth import earth_rate_enu
from analysis.identification import plan as ip
from analysis.identification.batch import batch_identify
from analysis.identification.kalman import StreamingIdentifier
from analysis.identification.specification import UnitModel, get_model, model_for_names
from analysis.units import ARCSEC, DEG, DEG_PER_HOUR, DEG_PER_SQRT_HOUR, G0, PPM, UG

from ...identification_synth import TRUTH as ACC_TRUTH

LAT = math.radians(48.15)
GYRO_TRUTH = np.array(
    [0.5 * DEG_PER_HOUR, -0.3 * DEG_PER_HOUR, 0.4 * DEG_PER_HOUR]
    + [50 * PPM, -40 * PPM, 60 * PPM]
    + [a * ARCSEC for a in (10.0, -8.0, 6.0, 12.0, -9.0, 7.0)]
    + [0.02 * DEG_PER_HOUR / G0, -0.03 * DEG_PER_HOUR / G0, 0.025 * DEG_PER_HOUR / G0]
)
"""The spec's typical gyro truth (0.5 °/h, 50 ppm, 10″, 0.02 °/h/g), SI, default model order."""


def _unit() -> UnitModel:
    return UnitModel((get_model("accelerometer"), get_model("gyro")))


def _steps(fast: bool = True) -> list[ip.PlanStep]:
    """Ten-step(-fast-spin) nominal samples with the Earth rate in the body frame (every 10th sample)."""
    steps = ip.ten_step_sequence(
        9.80, 10.0, hold_s=60.0, spin_rate=(60.0 if fast else 1.6) * DEG, revolutions=2.0 if fast else 1.0,
        both_directions=fast,
    )  # fmt: skip
    out = []
    for st in steps:
        c_bn = gimbal.body_to_nav(st.angles)
        earth = np.einsum("nji,j->ni", c_bn, earth_rate_enu(LAT))
        out.append(ip.PlanStep(st.label, st.f_ref, st.omega, st.weights, st.angles, earth))
    return out


def _noise(model) -> np.ndarray:  # noqa: ANN001
    fs = 10.0
    acc = (15 * UG) ** 2 * fs
    gyr = (0.01 * DEG_PER_SQRT_HOUR) ** 2 * fs
    return np.array([acc] * 3 + [gyr] * 3)[: model.n_axes]


def test_gyro_design_matrix_is_the_model_and_correct_is_its_exact_inverse() -> None:
    rng = np.random.default_rng(1)
    f = rng.normal(0, 9.8, (40, 3))
    om = rng.normal(0, 1.0, (40, 3))
    ea = rng.normal(0, 7e-5, (40, 3))
    for opts in ({}, {"full_g": True}, {"full_g": True, "quadratic": True, "asymmetry": True}):
        m = get_model("gyro", **opts)
        x = rng.normal(0, 1e-3, m.n_params)
        e = m.error_matrices(x)
        w = om + ea
        direct = w @ e["M"].T + e["b"] + f @ e["G"].T + e["S2"] * w**2 + e["A"] * np.abs(w)  # the equation
        np.testing.assert_allclose(m.predict(x, f, om, ea), direct, rtol=0, atol=1e-15)
        h = m.design_matrix(f, om, ea)
        np.testing.assert_allclose(m.ideal(f, om, ea) + np.einsum("nij,j->ni", h, x), direct, rtol=0, atol=1e-14)
        np.testing.assert_allclose(m.correct(x, direct, f), w, rtol=0, atol=1e-14)
        assert model_for_names(get_model("accelerometer").names + m.names).n_params == 18 + m.n_params
    names = get_model("gyro").names
    assert names[:6] == ("gyro_b_x", "gyro_b_y", "gyro_b_z", "gyro_S_x", "gyro_S_y", "gyro_S_z")
    assert names[6:12] == tuple(f"gyro_tau_{p}" for p in ("xy", "xz", "yx", "yz", "zx", "zy"))
    assert names[12:] == ("gyro_G_xx", "gyro_G_yy", "gyro_G_zz")


def test_noise_free_model_exact_record_gives_every_gyro_parameter_within_1e_3_sigma() -> None:
    m = _unit()
    x = np.concatenate([ACC_TRUTH, GYRO_TRUTH])
    steps = _steps()
    y = np.concatenate([m.predict(x, s.f_ref, s.omega, s.earth) for s in steps])
    f = np.concatenate([s.f_ref for s in steps])
    om = np.concatenate([s.omega for s in steps])
    ea = np.concatenate([s.earth for s in steps])
    res = batch_identify(y, f, om, _noise(m), model=m, earth=ea)  # no prior: nothing pulls the estimate
    assert res.rank == m.n_params
    err_over_sigma = (res.x - x) / res.sigma
    assert np.max(np.abs(err_over_sigma[18:])) < 1e-3, err_over_sigma[18:]
    assert np.max(np.abs(err_over_sigma[:18])) < 1e-3


def test_whole_unit_kalman_equals_batch_and_the_accelerometer_block_is_the_18_state_one() -> None:
    m = _unit()
    rng = np.random.default_rng(4)
    x = np.concatenate([ACC_TRUTH, GYRO_TRUTH])
    steps = _steps()
    r = _noise(m)
    p0 = np.diag(np.concatenate([np.abs(ACC_TRUTH) * 10 + 1e-12, np.abs(GYRO_TRUTH) * 10 + 1e-12]) ** 2)
    kf = StreamingIdentifier(r, p0, model=m)
    kf18 = StreamingIdentifier(r[:3], p0[:18, :18])
    ys, fs, oms, eas = [], [], [], []
    for s in steps:
        y = m.predict(x, s.f_ref, s.omega, s.earth) + rng.normal(0, np.sqrt(r), (s.f_ref.shape[0], 6))
        kf.update(y, s.f_ref, s.omega, s.label, earth=s.earth)
        kf18.update(y[:, :3], s.f_ref, s.omega, s.label)
        ys.append(y), fs.append(s.f_ref), oms.append(s.omega), eas.append(s.earth)
    b = batch_identify(np.concatenate(ys), np.concatenate(fs), np.concatenate(oms), r, None, p0, model=m,
                       earth=np.concatenate(eas))  # fmt: skip
    assert np.max(np.abs(kf.estimate - b.x) / np.maximum(np.abs(b.x), b.sigma)) < 1e-9
    assert np.max(np.abs(kf.covariance - b.covariance) / np.outer(b.sigma, b.sigma)) < 1e-9
    # the triads share no state: the accelerometer block is the 18-state identification's
    assert np.max(np.abs(kf.estimate[:18] - kf18.estimate) / kf18.sigma) < 1e-9
    assert np.all(np.abs(b.x - x) < 5 * b.sigma)


def test_plan_flags_g_at_one_minute_holds_and_scale_from_slow_one_direction_spins() -> None:
    m = _unit()
    mag = np.concatenate([np.abs(ACC_TRUTH), np.abs(GYRO_TRUTH)])
    p0 = np.diag((10 * mag) ** 2)
    b = np.array([3 * UG] * 3 + [0.05 * DEG_PER_HOUR] * 3)
    fast = ip.plan_identification(_steps(True), _noise(m), p0, b, magnitudes=mag, model=m)
    slow = ip.plan_identification(_steps(False), _noise(m), p0, b, magnitudes=mag, model=m)
    g_names = {"gyro_G_xx", "gyro_G_yy", "gyro_G_zz"}
    assert g_names <= set(fast.unidentifiable) and g_names <= set(slow.unidentifiable)
    assert any("gyro g-sensitivity" in w and "hold" in w for w in fast.warnings)
    scale = {f"gyro_S_{a}" for a in "xyz"}
    assert not scale & set(fast.unidentifiable)  # 60 °/s both ways: identified
    # 1.6 °/s, one direction: S_g only weakly identified (σ ≈ 12 ppm of 50 ppm, bias-stability limited) and
    # the smaller misalignments not at all — said before motion
    assert any(w.startswith("gyro_S_x, gyro_S_y, gyro_S_z (gyro scale factor) only weakly") for w in slow.warnings)
    assert any("gyro misalignment" in w and "1.6 °/s" in w for w in slow.warnings)
    assert not any("gyro scale factor" in w for w in fast.warnings)
    assert "gyro_b_x" in fast.table()


def test_against_imucal_ferraris_closed_form_without_earth_rate() -> None:
    import imucal  # a test dependency (pyproject test extras): missing → the suite fails, it does not skip
    gm = get_model("gyro", full_g=True)
    m = UnitModel((get_model("accelerometer"), gm))
    rng = np.random.default_rng(7)
    acc = ACC_TRUTH.copy()
    acc[12:] = 0.0  # imucal's accelerometer model has no quadratic or size-effect term
    gyr = np.concatenate([GYRO_TRUTH[:12], rng.normal(0, 0.05 * DEG_PER_HOUR / G0, 9)])  # full G
    x = np.concatenate([acc, gyr])
    fs_hz, g = 100.0, 9.80
    up = {"x": (0.0, 0.0, -90.0), "y": (0.0, 90.0, 0.0), "z": (0.0, 0.0, 0.0)}  # (ψ, θ, γ) deg: axis up
    regions: dict[str, np.ndarray] = {}
    f_all, om_all, y_all = [], [], []

    def record(angles: np.ndarray, rates: np.ndarray) -> np.ndarray:
        f = gimbal.gravity_in_body(angles, g)
        om = gimbal.body_rate(angles, rates)
        y = m.predict(x, f, om)  # no Earth rate (imucal ignores it)
        f_all.append(f), om_all.append(om), y_all.append(y)
        return y

    for ax, base in up.items():
        for sign, tag in ((1.0, "p"), (-1.0, "a")):
            a = np.radians(np.array(base, dtype=float))
            if sign < 0:
                a = a + np.radians([0.0, 0.0, 180.0] if ax == "x" else [0.0, 180.0, 0.0])  # the axis down
            y = record(np.tile(a, (200, 1)), np.zeros((200, 3)))
            regions[f"acc_{ax}_{tag}"], regions[f"gyr_{ax}_{tag}"] = y[:, :3], y[:, 3:] / DEG
        # one revolution about the up axis (the outer gimbal turns about the vertical = body axis ax), +10 °/s
        n = 3600
        a = np.tile(np.radians(np.array(base, dtype=float)), (n, 1))
        a[:, 0] += 10.0 * DEG * (np.arange(n) + 0.5) / fs_hz
        rates = np.zeros((n, 3))
        rates[:, 0] = 10.0 * DEG
        y = record(a, rates)
        regions[f"acc_{ax}_rot"], regions[f"gyr_{ax}_rot"] = y[:, :3], y[:, 3:] / DEG
    cal = imucal.FerrarisCalibration(grav=g, expected_angle=360.0).compute(
        imucal.FerrarisSignalRegions(**regions), fs_hz, from_acc_unit="m/s^2", from_gyr_unit="deg/s"
    )
    # the gyro block of the unit model (the triads share no state; six ±g positions leave the accelerometer's
    # S and d inseparable, which is the accelerometer's business, not this test's)
    res = batch_identify(np.concatenate(y_all)[:, 3:], np.concatenate(f_all), np.concatenate(om_all), 1e-12, model=gm)
    e = gm.error_matrices(res.x)
    np.testing.assert_allclose(e["M"], cal.K_g @ cal.R_g, rtol=0, atol=1e-9)  # I + S_g + T_g
    np.testing.assert_allclose(e["b"], np.asarray(cal.b_g) * DEG, rtol=0, atol=1e-12)  # rad/s
    np.testing.assert_allclose(e["G"], np.asarray(cal.K_ga) * DEG, rtol=0, atol=1e-12)  # rad/s per m/s²
    # and both are the truth (noise-free, exact models)
    np.testing.assert_allclose(res.x, gyr, rtol=0, atol=1e-12)


def test_whole_unit_correction_is_the_exact_joint_inverse() -> None:
    """correct_outputs(predict(x, f, ω)) = (f, ω) for a unit with the rate-transfer terms (rounding level)."""
    m = UnitModel((get_model("accelerometer"), get_model("gyro", full_g=True, quadratic=True, asymmetry=True)))
    rng = np.random.default_rng(9)
    x = np.concatenate([ACC_TRUTH, rng.normal(0, 1e-4, m.n_params - 18)])
    f = rng.normal(0, 9.8, (500, 3))
    om = rng.normal(0, 2.0, (500, 3))
    y = m.predict(x, f, om)
    back = m.correct_outputs(x, y)
    np.testing.assert_allclose(back[:, :3], f, rtol=0, atol=1e-12)
    np.testing.assert_allclose(back[:, 3:], om, rtol=0, atol=1e-14)

"""Simulated unit noise, periodic and ARMA terms against independent references; determinism."""

from __future__ import annotations

import math
from dataclasses import replace

import allantools
import numpy as np
import pytest
from statsmodels.tsa.arima_process import ArmaProcess
from statsmodels.tsa.stattools import acf

from analysis.units import DEG, DEG_PER_HOUR, DEG_PER_SQRT_HOUR, UG
from drivers.imu_unit.counts import frames_to_block
from drivers.protocols import FaultCode
from drivers.sim.config import (
    ArmaDrift,
    NoiseTruth,
    PeriodicTerm,
    ScheduledFault,
    SimConfig,
    TemperatureModel,
    example_navigation_grade,
)
from drivers.sim.world import SimulatedWorld


def _static(cfg: SimConfig, n: int, seed: int = 1) -> np.ndarray:
    w = SimulatedWorld(replace(cfg, table=replace(cfg.table, watchdog=None)), seed)
    b = frames_to_block(w.produce(n), w.scale)
    return np.hstack([b.accel, b.gyro])


def test_white_noise_density_matches_configuration() -> None:
    vrw = (10 * UG, 15 * UG, 20 * UG)
    arw = (0.01 * DEG_PER_SQRT_HOUR, 0.02 * DEG_PER_SQRT_HOUR, 0.05 * DEG_PER_SQRT_HOUR)
    cfg = SimConfig(accel_noise=NoiseTruth(white=vrw), gyro_noise=NoiseTruth(white=arw))
    fs = cfg.sample_rate
    x = _static(cfg, 60_000)
    x = x - x.mean(0)
    std = x.std(0)
    # per-sample std N·√f_s (IEEE convention: Allan deviation N/√τ)
    np.testing.assert_allclose(std, np.array(vrw + arw) * math.sqrt(fs), rtol=0.02)
    # cross-check the density with allantools: ADEV(τ) = N/√τ (τ = 0.1 s: ~900 degrees of freedom)
    for ch, n in enumerate(vrw + arw):
        taus, ad, _, _ = allantools.oadev(x[:, ch], rate=fs, data_type="freq", taus=np.array([0.1]))[:4]
        assert ad[0] == pytest.approx(n / math.sqrt(0.1), rel=0.1)
    # the channels are independent
    c = np.corrcoef(x.T)
    assert np.max(np.abs(c - np.eye(6))) < 0.03


def test_bias_instability_allan_floor() -> None:
    b = 3 * UG
    cfg = SimConfig(sample_rate=10.0, accel_noise=NoiseTruth(bias_instability=(b, b, b)))
    x = _static(cfg, 400_000, seed=2)[:, 0]
    taus, ad, _, _ = allantools.oadev(x, rate=10.0, data_type="freq", taus=np.array([3.0, 10.0, 30.0, 100.0]))[:4]
    # flicker floor 0.664 B (IEEE 952); the Gauss–Markov-sum approximation is flat to a few % over the band
    np.testing.assert_allclose(ad, 0.664 * b, rtol=0.15)


def test_random_walk_allan_slope() -> None:
    k = 0.5 * DEG_PER_HOUR / 60.0  # 0.5 °/h/√h in rad/s/√s
    cfg = SimConfig(sample_rate=10.0, gyro_noise=NoiseTruth(random_walk=(k, k, k)))
    x = _static(cfg, 200_000, seed=3)[:, 3:]
    x = x - x.mean(0)
    for ch in range(3):
        taus, ad, _, _ = allantools.oadev(x[:, ch], rate=10.0, data_type="freq", taus=np.array([100.0]))[:4]
        assert ad[0] == pytest.approx(k * math.sqrt(100.0 / 3.0), rel=0.5)


def test_periodic_terms_amplitude_and_phase() -> None:
    terms = (
        PeriodicTerm("gyro_x", 80.13, 0.6 * DEG, math.radians(20)),
        PeriodicTerm("gyro_x", 127.43, 0.3 * DEG, math.radians(110)),
        PeriodicTerm("accel_y", 3.7, 50 * UG, 0.0),
    )
    cfg = SimConfig(periodic=terms, gyro_noise=NoiseTruth(white=(0.2 * DEG_PER_SQRT_HOUR,) * 3))
    n = 8000
    x = _static(cfg, n)
    t = np.arange(n) / cfg.sample_rate
    for ch, fr in ((3, (80.13, 127.43)), (1, (3.7,))):
        cols = [np.ones(n)] + [f(2 * np.pi * q * t) for q in fr for f in (np.cos, np.sin)]
        coef, *_ = np.linalg.lstsq(np.stack(cols, 1), x[:, ch], rcond=None)
        for i, q in enumerate(fr):
            a, bb = coef[1 + 2 * i], coef[2 + 2 * i]
            term = next(p for p in terms if p.frequency_hz == q)
            assert math.hypot(a, bb) == pytest.approx(term.amplitude, rel=5e-3)
            assert math.atan2(-bb, a) == pytest.approx(term.phase, abs=5e-3)


def test_arma_drift_matches_statsmodels_acf() -> None:
    sigma = 2.0 * DEG_PER_HOUR
    cfg = SimConfig(arma=(ArmaDrift("gyro_z", phi=(0.9,), theta=(0.4,), sigma=sigma),))
    x = _static(cfg, 50_000)[:, 5]
    x = x - x.mean()
    # docs/methods/drift.md convention x_t − φ x_{t−1} = e_t − θ e_{t−1}  ↔  statsmodels ma = [1, −θ]
    proc = ArmaProcess(ar=[1, -0.9], ma=[1, -0.4])
    np.testing.assert_allclose(acf(x, nlags=5)[1:], proc.acf(6)[1:], atol=0.03)
    var_theory = sigma**2 * (1 + 0.4**2 - 2 * 0.9 * 0.4) / (1 - 0.9**2)
    assert x.var() == pytest.approx(var_theory, rel=0.1)


def test_temperature_warmup_drift() -> None:
    tm = TemperatureModel(ambient_c=20.0, warmup_rise_c=10.0, warmup_tau=50.0, accel_bias_tc=(10 * UG, 0, 0))
    cfg = SimConfig(sample_rate=100.0, temperature=tm)
    w = SimulatedWorld(replace(cfg, table=replace(cfg.table, watchdog=None)), 0)
    b = frames_to_block(w.produce(100 * 400), w.scale)
    assert b.temperature[0] == pytest.approx(293.15, abs=0.01)
    assert b.temperature[-1] == pytest.approx(303.15, abs=0.01)
    # bias drift follows the temperature; zero when settled
    assert b.accel[0, 0] == pytest.approx(-100 * UG, abs=0.5 * UG)
    assert b.accel[-1, 0] == pytest.approx(0.0, abs=0.5 * UG)


def _busy_config() -> SimConfig:
    cfg = example_navigation_grade()
    return replace(
        cfg,
        accel_noise=replace(cfg.accel_noise, random_walk=(1e-6,) * 3),
        gyro_noise=replace(cfg.gyro_noise, random_walk=(1e-7,) * 3),
        temperature=TemperatureModel(warmup_rise_c=5.0, warmup_tau=100.0, gyro_bias_tc=(1e-6, 0, 0)),
        periodic=(PeriodicTerm("gyro_x", 80.13, 0.01, 0.3),),
        arma=(ArmaDrift("gyro_y", (0.9,), (0.4,), 1e-5), ArmaDrift("accel_z", (0.5, 0.2), (), 1e-5)),
        anti_alias_hz=250.0,
        timestamp_jitter=2e-6,
        drop_probability=0.01,
        faults=(ScheduledFault(2.2, FaultCode.STALL),),
        table=replace(cfg.table, watchdog=None),  # heartbeats differ between the splits below
    )


def _run(world: SimulatedWorld, splits: list[int]) -> list:
    world.command_position([0.5, -0.2, 1.0])
    world.command_rate(0, 20 * DEG)
    out = []
    for n in splits:
        out.append(world.produce(n))
        world.heartbeat()
    return out


def _cat(frames: list, field: str) -> np.ndarray:
    return np.concatenate([getattr(f, field) for f in frames])


@pytest.mark.parametrize("splits", [[1000, 1500], [1, 999, 700, 800], [2500]])
def test_same_seed_identical_frames_regardless_of_split(splits: list[int]) -> None:
    cfg = _busy_config()
    ref = _run(SimulatedWorld(cfg, 42), [2500])
    got = _run(SimulatedWorld(cfg, 42), splits)
    for field in ("counter", "timestamp_ns", "counts", "temperature", "status"):
        np.testing.assert_array_equal(_cat(got, field), _cat(ref, field))


def test_split_with_table_readings_and_fault_in_between() -> None:
    cfg = _busy_config()
    a, b = SimulatedWorld(cfg, 9), SimulatedWorld(cfg, 9)
    fa = a.produce(3000)
    fb = [b.produce(1234)]
    sa = b.table_state()
    fb += [b.produce(1766)]
    np.testing.assert_array_equal(fa.counts, _cat(fb, "counts"))
    assert a.table_state().fault_code == b.table_state().fault_code == FaultCode.STALL
    # readings are a function of the sample index only
    c = SimulatedWorld(cfg, 9)
    c.produce(1234)
    np.testing.assert_array_equal(c.table_state().angles, sa.angles)


def test_different_seed_differs() -> None:
    cfg = _busy_config()
    fa = SimulatedWorld(cfg, 1).produce(500)
    fb = SimulatedWorld(cfg, 2).produce(500)
    assert not np.array_equal(fa.counts, fb.counts)

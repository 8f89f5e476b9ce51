"""End to end on the simulated unit: the bench's configured periodic terms are identified from
SimInertialUnit data (benches/sim-gyro-noise.yaml: three gyro_x terms, one gyro_y term, ARMA-coloured
drift, bias instability and rate random walk on top — the noise is *not* white here)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from analysis.periodic.compensator import PeriodicCompensator
from analysis.periodic.identify import identify_periodic
from analysis.periodic.linear import fit_fixed_frequencies
from benches.bench_config import BenchConfig, load_bench
from drivers.sim.inprocess import SimInertialUnit
from drivers.sim.world import SimulatedWorld
from tests import REPO_ROOT

BENCH = REPO_ROOT / "benches" / "sim-gyro-noise.yaml"


@pytest.fixture(scope="module")
def sim_data() -> tuple[BenchConfig, float, np.ndarray]:
    bench = load_bench(BENCH)
    unit = SimInertialUnit(SimulatedWorld.from_bench(bench))
    blocks = [unit.read(2000) for _ in range(8)]  # 16 s at 1 kHz, in driver-sized blocks
    gyro = np.concatenate([b.gyro for b in blocks])
    assert sum(b.dropped for b in blocks) == 0
    return bench, unit.sample_rate, gyro


def test_configured_terms_identified_from_sim_unit(sim_data) -> None:
    bench, rate, gyro = sim_data
    channels = {"gyro_x": 0, "gyro_y": 1, "gyro_z": 2}
    configured = bench.simulation.periodic
    n_cal = int(8 * rate)
    for name, col in channels.items():
        truth = sorted((p for p in configured if p.channel == name), key=lambda p: p.frequency_hz)
        model = identify_periodic(gyro[:n_cal, col], rate)
        terms = sorted(model.terms, key=lambda t: t.frequency_hz)
        assert len(terms) == len(truth), (name, [t.frequency_hz for t in terms])
        for t, p in zip(terms, truth, strict=True):
            # 5 reported standard errors (white-noise σ̂ of the residual: the drift is coloured, so allow 5σ)
            assert abs(t.frequency_hz - p.frequency_hz) < 5 * t.frequency_sigma_hz, (name, t, p)
            assert abs(t.amplitude - p.amplitude) < 5 * t.amplitude_sigma, (name, t, p)
            dphi = math.remainder(t.phase_rad - p.phase, 2 * math.pi)
            assert abs(dphi) < 5 * t.phase_sigma_rad, (name, t, p)


def test_compensation_of_sim_unit_removes_the_terms(sim_data) -> None:
    _, rate, gyro = sim_data
    n_cal = int(8 * rate)
    x = gyro[:, 0]
    model = identify_periodic(x[:n_cal], rate)
    after = model.compensator(start_index=n_cal).process(x[n_cal:] - model.offset)
    before = x[n_cal:] - model.offset
    # the remaining record is dominated by the configured noise once the terms are gone
    assert np.sqrt(np.mean(after**2)) < 0.25 * np.sqrt(np.mean(before**2))
    assert np.sqrt(np.mean(after**2)) == pytest.approx(model.noise_sigma, rel=0.1)


@pytest.mark.slow
def test_two_hour_sim_record_compensated_without_phase_drift() -> None:
    """2 h of SimInertialUnit data (≈80 s to simulate): compensating gyro_x with the bench's configured terms,
    block by block, leaves no tone at the end of the run — the compensator's phase (fixed-point, absolute
    index) and the simulator's (its own k·f/f_s mod 1) still agree after 7.2e6 samples."""
    bench = load_bench(BENCH)
    unit = SimInertialUnit(SimulatedWorld.from_bench(bench))
    rate = unit.sample_rate
    terms = [p for p in bench.simulation.periodic if p.channel == "gyro_x"]
    comp = PeriodicCompensator(
        [p.frequency_hz for p in terms], [p.amplitude for p in terms], [p.phase for p in terms], rate
    )
    chunk = 60_000
    n_chunks = int(round(2 * 3600 * rate)) // chunk
    for i in range(n_chunks):
        block = unit.read(chunk)
        assert block.dropped == 0
        out = comp.process(block.gyro[:, 0])
        if i in (0, n_chunks - 1):
            c0, amps, _, rss = fit_fixed_frequencies(out, rate, [p.frequency_hz for p in terms])
            sigma = np.sqrt(rss / out.size)
            # what is left at the configured frequencies is noise: amplitude estimates ~ σ √(2/N) each
            assert np.all(amps < 5 * sigma * np.sqrt(2 / out.size)), (i, amps)

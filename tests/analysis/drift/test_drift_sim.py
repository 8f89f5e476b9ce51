"""End to end: the ARMA drift configured on the simulated unit (benches/sim-gyro-noise.yaml) is recovered from
SimInertialUnit samples by the drift analysis.

The bench puts ARMA(1,1) drift (φ = 0.9, θ = 0.4, Box–Jenkins signs, σ = 2 °/h per sample) on the gyros under a
white angle random walk ~190 times larger at 1 kHz, so the world is rebuilt with the gyro noise terms off
(everything else — bias, Earth rate, quantisation, periodic terms — as configured) to make the drift the
dominant random term, as a drift-characterisation record would be after averaging.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from analysis.drift.report import analyse_drift
from benches.bench_config import load_bench
from drivers.sim.config import NoiseTruth, SimConfig
from drivers.sim.inprocess import SimInertialUnit
from drivers.sim.world import SimulatedWorld
from tests import REPO_ROOT

ROOT = REPO_ROOT
BENCH = ROOT / "benches" / "sim-gyro-noise.yaml"


def _record(seconds: float, rate: float, periodic: bool, seed: int) -> tuple[dict, float, SimConfig]:
    sim = load_bench(BENCH).simulation
    cfg = dataclasses.replace(
        sim,
        sample_rate=rate,
        anti_alias_hz=None,
        gyro_noise=NoiseTruth(),
        periodic=sim.periodic if periodic else (),
    )
    world = SimulatedWorld(cfg, seed)
    blk = SimInertialUnit(world).read(int(round(seconds * rate)))
    assert blk.dropped == 0
    return {f"gyro_{a}": blk.gyro[:, i] for i, a in enumerate("xyz")}, world.sample_rate, cfg


def test_sim_arma_drift_recovered() -> None:
    chans, fs, cfg = _record(500.0, 100.0, periodic=False, seed=3)
    out = analyse_drift(chans, fs, online=True, smoother_samples=2000)
    truth = {t.channel: t for t in cfg.arma}
    for name, ch in out["channels"].items():
        m = ch["model"]
        t = truth[name]
        assert (m["p"], m["q"]) == (1, 1), (name, m)
        assert abs(m["phi"][0] - t.phi[0]) < 3 * m["se_phi"][0], (name, m)
        assert abs(m["theta"][0] - t.theta[0]) < 3 * m["se_theta"][0], (name, m)
        assert abs(np.sqrt(m["sigma2"]) / t.sigma - 1.0) < 0.02, (name, m["sigma2"])
        assert ch["tests"]["ljung_box"]["verdict"] == "pass"
        assert abs(ch["online"]["phi"][0] - m["phi"][0]) < m["se_phi"][0]
        assert ch["compensation"]["std_after_filter"] < ch["compensation"]["std_before"]


def test_sim_periodic_terms_are_handed_off() -> None:
    """With the bench's periodic gyro errors on, the tones are listed for 'tablebench periodic' and removed."""
    chans, fs, cfg = _record(60.0, 400.0, periodic=True, seed=4)
    out = analyse_drift({"gyro_x": chans["gyro_x"]}, fs, online=False, smoother_samples=500)
    ch = out["channels"]["gyro_x"]
    tones = ch["tones_hz"]
    for term in cfg.periodic:
        if term.channel == "gyro_x":
            assert any(abs(f - term.frequency_hz) < 0.2 for f in tones), (term, tones)
    assert ch["tests"]["welch_periodicity"]["verdict"] == "reject"
    assert len(ch["tones_removed"]) == len(tones)

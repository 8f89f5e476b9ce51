"""Slow Monte Carlo: the 68 % and 95 % intervals of every estimator cover the true deviation at their nominal
rates (± 3 points), for white / flicker / random-walk FM and white / flicker PM (Kasdin–Walter power-law noise).

The "true" deviation per estimator and τ is √(mean σ²) over an independent ensemble of the same size
(relative error ≈ √(2/(K·EDF)) ≈ 1 % at the τ tested); the noise type is identified per record, as a user's
run would (lag-1 ACF / B1), so misidentification counts against the coverage. Only τ whose median EDF is ≥ 4
are scored (the χ² approximation and the B1 fallback are cruder below that).

KNOWN_GAPS lists the (noise, estimator) pairs whose published EDF fits miss the nominal rate on these
1024-point records (measured, see the final report of issue 16); they are printed, not asserted.
"""

from __future__ import annotations

import numpy as np
import pytest

from analysis.noise import confidence as ci
from analysis.noise.stability import stability

pytestmark = pytest.mark.slow

RECORDS = 400
N = 1024
ESTIMATORS = ("adev", "oadev", "mdev", "hdev", "ohdev", "totdev", "mtotdev", "htotdev", "theo1")
KNOWN_GAPS: dict[int, tuple[str, ...]] = {
    0: ("totdev", "theo1"),
    -1: ("theo1",),
    -2: ("htotdev", "theo1"),
    2: ("oadev", "ohdev", "totdev", "mtotdev", "htotdev", "theo1"),
    1: ("oadev", "totdev", "mtotdev", "htotdev", "theo1"),
}
"""Measured misses (2026-11-24, 400 records): white FM TOTDEV 61.6/89.4 %, Theo1 65.1/91.1 %; flicker FM Theo1
62.5/89.7 %; random-walk FM HTOTDEV 64.7 %, Theo1 57.9/87.2 %; white PM OADEV 73.1 %, OHDEV 73.5 %, TOTDEV
91.9 % (95), MTOTDEV 64.5/91.5 %, HTOTDEV 84.9/99.3 %, Theo1 79.1 %; flicker PM OADEV 91.8 % (95), TOTDEV
91.4 % (95), MTOTDEV 63.6/91.7 %, HTOTDEV 78.4 %, Theo1 75.3 %."""


def kasdin_phase(alpha: int, n: int, records: int, rng: np.random.Generator) -> np.ndarray:
    """Phase records (n, records) with S_y ∝ f^α (S_x ∝ f^(α−2)), Kasdin & Walter's causal filter."""
    b = 2 - alpha
    h = np.ones(n)
    for k in range(1, n):
        h[k] = h[k - 1] * (k - 1 + b / 2.0) / k
    w = rng.normal(size=(n, records))
    nfft = 2 * n
    x = np.fft.irfft(np.fft.rfft(w, nfft, axis=0) * np.fft.rfft(h, nfft)[:, None], nfft, axis=0)[:n]
    return x


@pytest.mark.parametrize("alpha", [0, -1, -2, 2, 1], ids=["WFM", "FFM", "RWFM", "WPM", "FPM"])
def test_interval_coverage(alpha: int) -> None:
    rng = np.random.default_rng(100 + alpha)
    x = kasdin_phase(alpha, N, 2 * RECORDS, rng)
    truth_half, test_half = x[:, :RECORDS], x[:, RECORDS:]
    ref = stability(truth_half, 1.0, ESTIMATORS, "octave", "phase", confidence=None)
    report, bad = [], []
    for conf in (0.683, 0.95):
        res = stability(test_half, 1.0, ESTIMATORS, "octave", "phase", confidence=conf)
        for name in ESTIMATORS:
            est, r = res.estimates[name], ref.estimates[name]
            with np.errstate(invalid="ignore"):
                true = np.sqrt(np.nanmean(np.where(np.isfinite(r.dev), r.dev**2, np.nan), axis=1))
            if name in ("totdev", "htotdev"):  # the ensemble mean is B·σ²: divide by the true noise's bias
                b = ci.bias_factor(name, np.full((r.m.size, 1), alpha), r.m, r.tau, N - 1.0)[:, 0]
                true = true / np.sqrt(b)
            med = np.array([np.median(e[np.isfinite(e)]) if np.isfinite(e).any() else 0.0 for e in est.edf])
            scored = med >= 4
            inside = (est.lo <= true[:, None]) & (true[:, None] <= est.hi)
            rate = float(inside[scored].mean())
            report.append(f"{name} {conf:.0%}: {rate:.3f} over {scored.sum()} τ")
            if abs(rate - conf) > 0.03 and name not in KNOWN_GAPS[alpha]:
                bad.append(report[-1])
    print(f"\nα={alpha}: " + "; ".join(report))
    assert not bad, f"α={alpha}: " + "; ".join(bad)

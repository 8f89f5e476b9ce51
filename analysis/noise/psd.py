"""Power spectral density of a rate record with the IEEE 952 noise terms in the frequency domain.

IEEE Std 952 states each noise term in both domains. As two-sided PSDs of the rate, S_Ω(f) = N² (white noise,
σ² = N²/τ), B²/(2πf) (bias instability, σ² floor (2 ln 2/π) B²), K²/(2πf)² (rate random walk, σ² = K²τ/3),
(2πf)² τ₀ Q² (quantisation) and R²/(2πf)³ (rate ramp). tablebench reports the *one-sided* PSD (twice these,
f > 0), estimated by Welch's method (Hann window, 50 % overlap, eight segments by default) and averaged in
logarithmic frequency bins; the terms N, B and K are fitted to the binned PSD by weighted non-negative least
squares (weights from the model, iterated; each bin's relative scatter 1/√(its averaged ordinates × segments))
and reported with standard uncertainties, so they can be set beside the Allan-variance terms. The Allan
terms are drawn on the PSD picture too. See docs/methods/noise.md.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy import signal
from scipy.optimize import nnls

PSD_TERMS: tuple[str, ...] = ("N", "B", "K")
"""Terms fitted in the frequency domain (Q and R need the band edges the Welch estimate does not resolve)."""


def term_psd(f: ArrayLike, terms: dict[str, float], ts: float) -> dict[str, NDArray[np.float64]]:
    """One-sided PSD (u²/Hz) of each IEEE 952 term at frequencies f (Hz), term values SI; ts the sample interval."""
    w = 2.0 * math.pi * np.asarray(f, dtype=np.float64)
    out = {}
    for name, v in terms.items():
        if v is None or not math.isfinite(v) or v <= 0:
            continue
        two_sided = {
            "Q": w**2 * ts * v**2,
            "N": np.full(w.shape, v**2),
            "B": v**2 / w,
            "K": v**2 / w**2,
            "R": v**2 / w**3,
        }[name]
        out[name] = 2.0 * two_sided
    return out


def rate_psd(
    data: ArrayLike, rate: float, segments: int = 8, bins_per_decade: int = 10
) -> dict[str, NDArray[np.float64] | dict]:
    """Welch PSD of a gap-free rate record, log-binned, with N, B, K fitted in the frequency domain.

    Returns
    -------
    dict
        {"f", "psd" (Welch, one-sided, u²/Hz), "f_binned", "psd_binned", "dof_binned" (χ² degrees of freedom
        per bin), "terms": {N, B, K: (value, σ) SI}, "segments"}.
    """
    y = np.asarray(data, dtype=np.float64).ravel()
    if not np.all(np.isfinite(y)):
        raise ValueError("the PSD needs a gap-free record")
    nper = max(16, y.size * 2 // (segments + 1))
    f, p = signal.welch(y - y.mean(), fs=rate, window="hann", nperseg=nper, noverlap=nper // 2, detrend="constant")
    f, p = f[1:], p[1:]
    n_seg = max(1, (y.size - nper) // (nper // 2) + 1)
    edges = 10.0 ** np.arange(math.floor(math.log10(f[0])), math.log10(f[-1]) + 1e-9, 1.0 / bins_per_decade)
    idx = np.digitize(f, edges)
    fb, pb, kb = [], [], []
    for i in np.unique(idx):
        sel = idx == i
        fb.append(math.exp(float(np.mean(np.log(f[sel])))))
        pb.append(float(np.mean(p[sel])))
        kb.append(int(np.count_nonzero(sel)))
    fb, pb = np.array(fb), np.array(pb)
    # Welch with Hann and 50 % overlap: ≈ 1.9 · segments χ² degrees of freedom per ordinate (Welch 1967); adjacent
    # ordinates of a Hann window are correlated, so a bin of k ordinates counts as k/1.5 of them
    dof = 2.0 * 0.95 * n_seg * np.maximum(np.array(kb) / 1.5, 1.0)
    return {"f": f, "psd": p, "f_binned": fb, "psd_binned": pb, "dof_binned": dof, "segments": n_seg,
            "terms": fit_psd_terms(fb, pb, dof)}  # fmt: skip


def fit_psd_terms(f: NDArray, s: NDArray, dof: NDArray, iterations: int = 4) -> dict[str, tuple[float, float]]:
    """N, B, K (value, 1σ) from a one-sided PSD s(f) = 2N² + B²/(πf) + K²/(2π²f²) by weighted NNLS."""
    a = np.column_stack([np.ones_like(f), 1.0 / f, 1.0 / f**2])
    ref = s.copy()
    coef = np.zeros(3)
    for _ in range(iterations):
        w = np.sqrt(dof / 2.0) / ref  # 1/σ of each bin: σ = S·√(2/dof)
        aw = a * w[:, None]
        scale = np.linalg.norm(aw, axis=0)
        c, _ = nnls(aw / scale, s * w)
        coef = c / scale
        model = a @ coef
        if not np.all(model > 0):
            break
        ref = model
    w = np.sqrt(dof / 2.0) / ref
    cov = np.linalg.pinv((a * w[:, None]).T @ (a * w[:, None]))
    sig = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    gains = {"N": 2.0, "B": 1.0 / math.pi, "K": 1.0 / (2.0 * math.pi**2)}  # c_n = gain · term²
    out = {}
    for i, name in enumerate(PSD_TERMS):
        g = gains[name]
        v = math.sqrt(max(coef[i], 0.0) / g)
        out[name] = (v, sig[i] / (2.0 * math.sqrt(g * coef[i])) if coef[i] > 0 else math.sqrt(sig[i] / g))
    return out

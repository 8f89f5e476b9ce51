"""The fast paths of analysis/noise/stability.py against straightforward references kept here.

The O(N) + O(m log m) closed forms of the total family and Theo1 (autocorrelation, end-segment FFT
correlations), the memory-lean autocorrelation, the chunked direct sums, the lazy phase of a record and the
channel-by-channel evaluation of several channels must give the same numbers as the definitions evaluated
window by window (allantools' loops, vectorised per window).
"""

from __future__ import annotations

import numpy as np
import pytest

from analysis.noise import closed_forms as cf
from analysis.noise import direct, fftkit, mtot, record, theo1
from analysis.noise.stability import stability


def _mtot_reference(s: np.ndarray, m: int) -> float:
    """Σ over 3m-point windows of the squared modified second differences of the detrended (half-mean slope)
    window extended by even reflection to 9m points (allantools' mtotdev loop, one window at a time)."""
    L = 3 * m
    h1 = L // 2
    D = (0.5 * (L - 1) + 1) if L % 2 else 0.5 * L
    tot = 0.0
    for i in range(s.size - L + 1):
        z = s[i : i + L]
        slope = (z[L - h1 :].sum() - z[:h1].sum()) / (h1 * D)
        z = z - slope * np.arange(L)
        e = np.concatenate([z[::-1], z, z[::-1]])
        c = np.concatenate([[0.0], np.cumsum(e)])
        j = np.arange(6 * m)
        t = (c[j + m] - c[j]) - 2.0 * (c[j + 2 * m] - c[j + m]) + (c[j + 3 * m] - c[j + 2 * m])
        tot += float(t @ t)
    return tot


def _theo1_reference(x: np.ndarray, m: int) -> float:
    h = m // 2
    tot = 0.0
    for i in range(x.size - m):
        d = np.arange(h)
        t = (x[i] - x[i + h - d]) + (x[i + m] - x[i + h + d])
        tot += float(np.sum(t * t / (h - d)))
    return tot


def _series(n: int, seed: int, kind: str) -> np.ndarray:
    rng = np.random.default_rng(seed)
    y = rng.normal(size=n) + 0.02 * np.cumsum(rng.normal(size=n)) + 3.0 * np.linspace(0.0, 1.0, n) ** 2 + 2.0
    return y if kind == "freq" else np.cumsum(y) * 1e-2


@pytest.mark.parametrize("kind", ["freq", "phase"])
@pytest.mark.parametrize(("n", "seed"), [(211, 1), (390, 2), (517, 3)])
def test_total_family_closed_form_equals_the_window_loop(n: int, seed: int, kind: str) -> None:
    s = _series(n, seed, kind)
    sd, a = fftkit.detrend_quadratic(s)
    r = fftkit.autocorr(sd, n - 1)
    for m in sorted({8, 9, 13, 16, n // 6, n // 3}):
        if 3 * m > n:
            continue
        ref = _mtot_reference(s, m)
        v, err = mtot.mtot_fft(sd, m, r, a)
        assert err < cf.FFT_MAX_ERR
        assert v == pytest.approx(ref, rel=1e-10), m
        d, k = direct.reflected_sumsq(s[None, :], m, None)  # the chunked direct sum
        assert d[0] == pytest.approx(ref, rel=1e-10) and k[0] == n - 3 * m + 1


@pytest.mark.parametrize(("n", "seed"), [(300, 4), (455, 5)])
def test_theo1_closed_form_equals_the_definition(n: int, seed: int) -> None:
    x = _series(n, seed, "phase")
    xd, a = fftkit.detrend_quadratic(x)
    r = fftkit.autocorr(xd, n - 1, 2)  # Theo1 reads the even lags only
    for m in (64, 66, 98, 2 * ((n - 3) // 2)):
        ref = _theo1_reference(x, m)
        v, err = theo1.theo1_fft(xd, m, r, a)
        assert err < cf.FFT_MAX_ERR
        assert v == pytest.approx(ref, rel=1e-10), m
        d, k = direct.theo1_sumsq(x[None, :], m, None)
        assert d[0] == pytest.approx(ref, rel=1e-10) and k[0] == (n - m) * (m // 2)


@pytest.mark.parametrize("n", [2, 7, 64, 1001, 4096])
def test_autocorrelation_equals_direct_lag_products(n: int) -> None:
    s = np.random.default_rng(n).normal(size=n) + 5.0
    r = fftkit.autocorr(s, n - 1)
    ref = np.array([s[: n - d] @ s[d:] for d in range(n)])
    np.testing.assert_allclose(r, ref, rtol=0, atol=1e-12 * ref[0])
    assert fftkit.autocorr(s, n // 2).size == n // 2 + 1
    np.testing.assert_allclose(fftkit.autocorr(s, n - 1, 2), ref[::2], rtol=0, atol=1e-12 * ref[0])
    np.testing.assert_allclose(fftkit.autocorr(s, n // 3, 3), ref[: n // 3 + 1 : 3], rtol=0, atol=1e-12 * ref[0])


def test_chunked_direct_sums_cross_chunk_boundaries(monkeypatch: pytest.MonkeyPatch) -> None:
    s = _series(700, 6, "freq")
    ref = {m: direct.reflected_sumsq(s[None, :], m, None)[0][0] for m in (1, 2, 5)}
    th = {m: direct.theo1_sumsq(s[None, :], m, None)[0][0] for m in (2, 8)}
    monkeypatch.setattr(direct, "CHUNK", 1024)  # the floor of the chunk: several chunks below
    s2 = np.concatenate([s] * 3)
    for m in ref:
        one = direct.reflected_sumsq(s[None, :], m, None)[0][0]
        assert one == pytest.approx(ref[m], rel=1e-13)
        ok = np.ones((1, s2.size - 3 * m + 1), dtype=bool)
        ok[0, 5:9] = False
        full, k = direct.reflected_sumsq(s2[None, :], m, None)
        part, kk = direct.reflected_sumsq(s2[None, :], m, ok)
        assert kk[0] == k[0] - 4 and part[0] < full[0]
    for m in th:
        assert direct.theo1_sumsq(s[None, :], m, None)[0][0] == pytest.approx(th[m], rel=1e-13)


@pytest.mark.parametrize("data_type", ["freq", "phase"])
def test_several_channels_equal_one_at_a_time(data_type: str) -> None:
    """The channel-by-channel pre-pass (several channels) gives each channel's single-channel result."""
    rng = np.random.default_rng(7)
    n = 1500
    data = rng.normal(size=(n, 3)) + 0.05 * np.cumsum(rng.normal(size=(n, 3)), axis=0)
    data[:, 1] += np.linspace(0.0, 2.0, n) ** 2
    if data_type == "phase":
        data = np.cumsum(data, axis=0) / 50.0
    names = ("mtotdev", "ttotdev", "htotdev", "theo1", "oadev", "mdev", "totdev", "adev")
    res = stability(data, 50.0, names, "octave", data_type, confidence=None)
    for ch in range(3):
        one = stability(np.ascontiguousarray(data[:, ch]), 50.0, names, "octave", data_type, confidence=None)
        for k in names:
            np.testing.assert_allclose(res.estimates[k].dev[:, ch], one.estimates[k].dev[:, 0], rtol=1e-12, err_msg=k)
            np.testing.assert_array_equal(res.estimates[k].n_terms[:, ch], one.estimates[k].n_terms[:, 0])


def test_record_phase_is_lazy_and_equals_the_integrated_frequency() -> None:
    rng = np.random.default_rng(8)
    y = rng.normal(size=(200_003, 2)) + 3.0
    rec = record.Record(y, 10.0, "freq")
    assert not rec.phase_formed and not rec.has_gaps
    x = rec.x
    ref = np.concatenate([np.zeros((1, 2)), np.cumsum(y - y.mean(axis=0), axis=0)], axis=0).T / 10.0
    np.testing.assert_allclose(x, ref, rtol=0, atol=1e-9 * np.abs(ref).max())
    assert rec.frequency()[0] is rec.freq_raw  # gap-free frequency: no copy
    phase = np.ascontiguousarray(ref[0])
    prec = record.Record(phase, 10.0, "phase")
    assert np.shares_memory(prec.x, phase)  # gap-free phase input: used as given
    yg = y.copy()
    yg[5, 1] = np.nan
    grec = record.Record(yg, 10.0, "freq")
    assert grec.has_gaps and int(grec.gap_samples[1]) == 1 and np.isfinite(grec.x).all()


def test_blocked_closed_form_equals_the_definition(monkeypatch: pytest.MonkeyPatch) -> None:
    """The block-by-block closed form (used where the record-wide rounding estimate is too large) sums the same
    windows: several blocks, the last one partial."""
    monkeypatch.setattr(cf, "BLOCK_MIN", 37)
    x = _series(610, 9, "phase")
    for m in (8, 11, 20):
        assert cf.blocked_sum(x, m, "mtot") == pytest.approx(_mtot_reference(x, m), rel=1e-10)
    for m in (64, 70):
        assert cf.blocked_sum(x, m, "theo1") == pytest.approx(_theo1_reference(x, m), rel=1e-10)


@pytest.mark.parametrize("n", [7, 40, 257])
def test_gap_free_totdev_from_oadev_terms_equals_the_reflected_definition(n):
    """Gap-free TOTDEV reuses OADEV's second differences for the centres m … N−1−m and forms only the end
    terms; it must equal the term-by-term reflected definition (_tot_sumsq) at every m up to N−2."""
    rng = np.random.default_rng(n)
    x = np.cumsum(rng.standard_normal((2, n)), axis=1)
    rec = record.Record(x.T, 1.0, "phase")
    for m in range(1, n):
        ref_s, ref_k = direct.tot_sumsq(rec, m)
        s, k = direct.tot_sumsq_central(rec, m, {})
        np.testing.assert_allclose(s, ref_s, rtol=1e-12, atol=0.0)
        np.testing.assert_array_equal(k, ref_k)


# ---------------------------------------------------------------- memory-lean long-τ machinery (issue 16)


@pytest.fixture
def small_blocks(monkeypatch: pytest.MonkeyPatch) -> None:
    """Force the blocked / in-place code paths that N = 10⁷ takes at long τ onto records of a few hundred points:
    in-place FFTs at every size, FFT blocks of a few dozen points, checkpoints every few values."""
    monkeypatch.setattr(fftkit, "IP_SMALL", 0)
    monkeypatch.setattr(fftkit, "IP_STEP", 3)
    monkeypatch.setattr(theo1, "LEAN_MIN", 16)
    monkeypatch.setattr(theo1, "TRI_BASE", 8)
    monkeypatch.setattr(mtot.ParityCumsum, "CH", 8)
    monkeypatch.setattr(mtot.Prefix, "CH", 6)


@pytest.mark.parametrize("nf", [2, 4, 6, 10, 64, 130, 1000, 4620])
def test_inplace_real_fft_equals_scipy(nf: int, small_blocks: None) -> None:
    x = np.random.default_rng(nf).normal(size=nf)
    ref = np.fft.rfft(x)
    z = fftkit.rfft_ip(x.copy())
    got = np.concatenate([[z[0].real], z[1:], [z[0].imag]])
    want = np.concatenate([[ref[0].real], ref[1:-1], [ref[-1].real]])
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-13 * np.abs(ref).max())
    np.testing.assert_allclose(fftkit.irfft_ip(z), x, rtol=0, atol=1e-14 * nf)


@pytest.mark.parametrize("m", [1, 2, 3, 5, 8, 13])
def test_kernel_closed_forms_equal_the_arrays(m: int, small_blocks: None) -> None:
    rho = mtot.kernel_rho(m)
    assert np.array_equal(mtot.rho_slice(m, 0, 6 * m), rho)
    spec = np.fft.rfft(rho)
    np.testing.assert_allclose(mtot.rho_spectrum(m, 0, 3 * m + 1), spec.real, rtol=0, atol=1e-13 * np.abs(spec).max())
    rc = np.zeros(6 * m + 2)
    rc[2::2] = np.cumsum(rho[0::2])
    rc[3::2] = np.cumsum(rho[1::2])
    pc = mtot.ParityCumsum(m)  # checkpoints every 8 values (or the whole array when 6m ≤ 8)
    for j0 in range(0, 6 * m + 2, 3):
        for j1 in range(j0 + 1, 6 * m + 3, 5):
            assert np.array_equal(pc.get(j0, j1), rc[j0:j1])
    v = np.random.default_rng(m).normal(size=3 * m + 4)
    pre = mtot.Prefix(lambda i, j: v[i:j], v.size)
    s = np.concatenate([[0.0], np.cumsum(v)])
    for j0 in range(-5, v.size + 3, 2):
        j1 = j0 + 9
        want = s[np.clip(np.arange(j0, j1), 0, v.size)]
        np.testing.assert_allclose(pre.at(j0, j1), want, rtol=0, atol=1e-12 * np.abs(s).max())


def test_blocked_correlation_sum_equals_the_double_sum(small_blocks: None) -> None:
    rng = np.random.default_rng(11)
    a, b = rng.normal(size=70), rng.normal(size=53)
    kern = rng.normal(size=200)  # K(l) = kern[l + 100], zero outside [lo, hi)
    for lo, hi in ((-100, 100), (0, 40), (-30, -5), (5, 6)):
        ref = sum(a[u] * b[v] * kern[v - u + 100] for u in range(a.size) for v in range(b.size) if lo <= v - u < hi)

        def k(l0: int, l1: int, lo: int = lo, hi: int = hi) -> np.ndarray:
            ll = np.arange(l0, l1)
            return np.where((ll >= lo) & (ll < hi), kern[np.clip(ll + 100, 0, 199)], 0.0)

        for cap in (16, 30, 1 << 10):  # blocks of 8 and 15 points, one FFT
            got = theo1.corr_sum(lambda i, j: a[i:j], a.size, lambda i, j: b[i:j], b.size, k, lo, hi, cap)
            assert got == pytest.approx(ref, rel=1e-12, abs=1e-12), (lo, hi, cap)


@pytest.mark.parametrize("kind", ["freq", "phase"])
@pytest.mark.parametrize(("n", "seed"), [(211, 1), (517, 3)])
def test_total_family_lean_paths_equal_the_window_loop(n: int, seed: int, kind: str, small_blocks: None) -> None:
    """The in-place buffers, slice-by-slice weights, on-demand detrended series and released R (a one-element list)
    give the window-by-window definition."""
    s = _series(n, seed, kind)
    for m in sorted({8, 9, 13, n // 6, n // 3}):
        if 3 * m > n:
            continue
        ref = _mtot_reference(s, m)
        d = fftkit.Detrended(s)
        r = fftkit.autocorr(d, 3 * m - 1)
        assert r.size == 3 * m
        v, err = mtot.mtot_fft(d, m, [r], d.a)
        assert err < cf.FFT_MAX_ERR
        assert v == pytest.approx(ref, rel=1e-10), m


@pytest.mark.parametrize(("n", "seed"), [(300, 4), (455, 5)])
def test_theo1_blocked_paths_equal_the_definition(n: int, seed: int, small_blocks: None) -> None:
    """Kernel pieces in the overlap-save correlation, blocked triangle squares (FFTs of ≤ 16–56 points here)."""
    x = _series(n, seed, "phase")
    xd, a = fftkit.detrend_quadratic(x)
    r = fftkit.autocorr(xd, n - 1, 2)
    for m in (64, 66, 98, 2 * ((n - 3) // 2)):
        ref = _theo1_reference(x, m)
        v, err = theo1.theo1_fft(xd, m, r, a)
        assert err < cf.FFT_MAX_ERR
        assert v == pytest.approx(ref, rel=1e-10), m


@pytest.mark.parametrize("data_type", ["freq", "phase"])
def test_stability_lean_paths_equal_the_default_ones(data_type: str, monkeypatch: pytest.MonkeyPatch) -> None:
    """Several channels (the channel-by-channel pre-pass, R released at the last m) and a record with gaps, the
    long-τ code paths forced onto small blocks, against the same call with the default sizes."""
    rng = np.random.default_rng(12)
    n = 1200
    data = rng.normal(size=(n, 2)) + 0.05 * np.cumsum(rng.normal(size=(n, 2)), axis=0)
    data[:, 1] += np.linspace(0.0, 2.0, n) ** 2
    if data_type == "phase":
        data = np.cumsum(data, axis=0) / 50.0
    gappy = data.copy()
    gappy[100:104, 0] = np.nan
    names = ("mtotdev", "ttotdev", "htotdev", "theo1")
    taus = np.array([2, 8, 16, 64, 100, 128, 200, 256, 330, 398]) / 50.0  # windows up to 3m ≈ N and m ≈ N/3
    ref = [stability(d, 50.0, names, taus, data_type, confidence=None) for d in (data, gappy)]
    lean = ((fftkit, "IP_SMALL", 0), (fftkit, "IP_STEP", 64), (theo1, "LEAN_MIN", 16), (theo1, "TRI_BASE", 8))
    for mod, attr, val in lean:
        monkeypatch.setattr(mod, attr, val)
    monkeypatch.setattr(mtot.ParityCumsum, "CH", 8)
    monkeypatch.setattr(mtot.Prefix, "CH", 10)
    for d, want in zip((data, gappy), ref, strict=True):
        got = stability(d, 50.0, names, taus, data_type, confidence=None)
        for k in names:
            np.testing.assert_allclose(got.estimates[k].dev, want.estimates[k].dev, rtol=1e-10, err_msg=k)
            np.testing.assert_array_equal(got.estimates[k].n_terms, want.estimates[k].n_terms)

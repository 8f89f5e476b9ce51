"""The chunked one-pass-per-τ implementation of analysis/noise/allan.py: chunk boundaries, skipped octaves, m
larger than a chunk, odd lengths, several channels, the phase it can leave behind, and its small helpers —
against allantools, the estimator definitions evaluated directly, and the same call with other chunk sizes."""

from __future__ import annotations

import allantools
import numpy as np
import pytest

import analysis.noise.allan as al
from analysis.noise import record
from analysis.noise.allan import ESTIMATORS, allan_variances
from analysis.noise.stability import stability

_AT = {"avar": "adev", "oavar": "oadev", "totvar": "totdev", "mvar": "mdev"}


def _record(n: int, seed: int, channels: int = 1) -> np.ndarray:
    rng = np.random.default_rng(seed)
    shape = (n, channels)
    y = rng.normal(size=shape) * 1e-3 + np.cumsum(rng.normal(size=shape), axis=0) * 1e-5
    y += 2e-6 * np.arange(n)[:, None] + 0.7
    return y if channels > 1 else y[:, 0]


def _definitions(y: np.ndarray, m: int) -> dict[str, float]:
    """The four variances of one channel straight from their definitions (extended precision, no chunks)."""
    n = y.size
    x = np.concatenate([[0.0], np.cumsum(y.astype(np.longdouble) - np.mean(y, dtype=np.longdouble))])
    out = {}
    d = x[2 * m :] - 2 * x[m:-m] + x[: -2 * m]
    out["oavar"] = float(np.mean(d**2) / (2 * m * m))
    k = n // m - 1
    out["avar"] = float(np.mean(d[: k * m : m] ** 2) / (2 * m * m))
    cd = np.concatenate([[0.0], np.cumsum(d)])
    s = cd[m:] - cd[:-m]
    if s.size:
        out["mvar"] = float(np.mean(s**2) / (2 * m**4))
    ext = np.concatenate([2 * x[0] - x[m:0:-1], x, 2 * x[-1] - x[-2 : -m - 2 : -1]])  # x*_{−m} … x*_{N+m}
    i = np.arange(1, n)
    dt = ext[i] - 2 * ext[i + m] + ext[i + 2 * m]
    out["totvar"] = float(np.sum(dt**2) / (2 * m * m * (n - 1)))
    return out


@pytest.mark.parametrize("n", [4, 5, 67, 1000, 4099])
@pytest.mark.parametrize("chunk", [16, 17, 37, 1024])
def test_every_chunk_size_gives_the_definitions(n: int, chunk: int) -> None:
    y = _record(n, n)
    res = allan_variances(y, 1.0, "octave", max_m=max(1, n // 3), chunk=chunk)
    for j, m in enumerate(res.m):
        ref = _definitions(y, int(m))
        for est in ESTIMATORS:
            if est in ref and res.n_terms[est][j] > 0:
                assert res.var[est][j, 0] == pytest.approx(ref[est], rel=1e-10), (est, int(m))


def test_m_larger_than_the_chunk_and_skipped_octaves() -> None:
    """Grid 2, 8, 32, 128 (the octaves between are doubled without sums) with chunks of 16 samples: most
    levels have m ≥ chunk (the three-slice branches) — equal to allantools and to the default chunk."""
    n, rate = 3001, 4.0
    y = _record(n, 3)
    taus = np.array([2, 8, 32, 128, 512]) / rate
    small = allan_variances(y, rate, taus, chunk=16)
    big = allan_variances(y, rate, taus)
    assert list(small.m) == [2, 8, 32, 128, 512]
    for est, fname in _AT.items():
        np.testing.assert_allclose(small.var[est], big.var[est], rtol=1e-12, err_msg=est)
        tt, dev, _, _ = getattr(allantools, fname)(y, rate=rate, data_type="freq", taus=small.tau)
        keep = small.n_terms[est] > 1
        np.testing.assert_allclose(np.sqrt(small.var[est][keep, 0]), dev, rtol=1e-10, err_msg=est)


def test_general_grid_matches_the_octave_passes_on_common_m() -> None:
    """A non-power-of-two grid takes the running-sum path; on the m both grids hold, the values agree."""
    y = _record(5003, 4)
    octave = allan_variances(y, 1.0, "octave", chunk=64)
    mixed = allan_variances(y, 1.0, [1, 2, 3, 4, 16, 100, 512, 1024], chunk=64)
    for m in (1, 2, 4, 16, 512, 1024):
        i, j = int(np.searchsorted(octave.m, m)), int(np.searchsorted(mixed.m, m))
        for est in ESTIMATORS:
            assert mixed.var[est][j, 0] == pytest.approx(octave.var[est][i, 0], rel=1e-11), (est, m)


def test_channels_strided_and_integer_input_equal_single_channel_calls() -> None:
    y = _record(2501, 5, channels=3)  # C-order (N, 3): each channel a strided column
    res = allan_variances(y, 10.0, chunk=32)
    for ch in range(3):
        one = allan_variances(np.ascontiguousarray(y[:, ch]), 10.0)
        for est in ESTIMATORS:
            np.testing.assert_allclose(res.var[est][:, ch], one.var[est][:, 0], rtol=1e-12, err_msg=est)
    counts = np.random.default_rng(6).integers(-500, 500, size=1000)
    ints = allan_variances(counts, 1.0)
    floats = allan_variances(counts.astype(np.float64), 1.0)
    for est in ESTIMATORS:
        np.testing.assert_array_equal(ints.var[est], floats.var[est])


def test_phase_left_behind_is_the_integrated_mean_removed_record() -> None:
    y = _record(20011, 7, channels=2)
    phase = np.empty((2, y.shape[0] + 1))
    with_phase = allan_variances(y, 50.0, phase=phase, chunk=1000)
    plain = allan_variances(y, 50.0, chunk=1000)
    for est in ESTIMATORS:
        np.testing.assert_array_equal(with_phase.var[est], plain.var[est])
    ref = record.Record(y, 50.0, "freq").x
    np.testing.assert_allclose(phase, ref, rtol=0, atol=1e-12 * np.abs(ref).max())
    with pytest.raises(ValueError, match="phase must be"):
        allan_variances(y, 50.0, phase=np.empty((1, y.shape[0] + 1)))


def test_stability_one_channel_adopts_the_phase_with_the_same_noise_identification() -> None:
    """One channel (the phase comes from the Allan pass) and the same record as the first of two channels (the
    phase integrated by the record) give the same deviations, noise types, EDF and intervals. The two phases
    differ at the rounding level (both ≈ 1e-14 of their largest value from an extended-precision sum); MTOTDEV of
    this ramp-dominated record, computed from the phase, moves by ≈ 3e-10 with that rounding."""
    y = _record(30000, 8)
    y2 = np.column_stack([y, _record(30000, 9)])
    names = ("adev", "oadev", "mdev", "totdev", "mtotdev")
    one = stability(y, 100.0, names, "octave")
    two = stability(y2, 100.0, names, "octave")
    for k in names:
        a, b = one.estimates[k], two.estimates[k]
        rtol = 1e-12 if k != "mtotdev" else 1e-9
        np.testing.assert_allclose(a.dev[:, 0], b.dev[:, 0], rtol=rtol, err_msg=k)
        np.testing.assert_array_equal(a.alpha[:, 0], b.alpha[:, 0])
        np.testing.assert_allclose(a.edf[:, 0], b.edf[:, 0], rtol=1e-12, err_msg=k)
        np.testing.assert_allclose(a.lo[:, 0], b.lo[:, 0], rtol=rtol, err_msg=k)


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_non_finite_sample_is_still_an_error(bad: float) -> None:
    y = _record(100, 10)
    y[57] = bad
    with pytest.raises(ValueError, match="NaN or inf"):
        allan_variances(y, 1.0)


@pytest.mark.parametrize("k", [0, 1, 4095, 4096, 4097, 3 * 4096 + 5])
def test_blocked_dot_equals_numpy(k: int) -> None:
    rng = np.random.default_rng(k)
    u, v = rng.normal(size=3 * k + 3), rng.normal(size=k)
    assert al.sum_of_products(v) == pytest.approx(float(v @ v), rel=1e-13, abs=1e-300)
    assert al.sum_of_products(u[::3][:k], v) == pytest.approx(float(u[::3][:k] @ v), rel=1e-12, abs=1e-12)


@pytest.mark.parametrize("half_a", [0.0, 3e-4])
def test_edge_sums_fast_form_equals_the_general_reflection(half_a: float) -> None:
    rng = np.random.default_rng(12)
    n = 1000
    x = np.concatenate([[0.0], np.cumsum(rng.normal(size=n))])
    bufs = al._Buffers(32, 64)
    for m in (1, 2, 31, 32, 33, 200, 500):
        fast = al.edge_sums(x, m, half_a, 32, bufs)
        general = al.edge_sum_general(x, m, 1, m - 1, half_a, 32) + al.edge_sum_general(
            x, m, n - m + 1, n - 1, half_a, 32
        )
        assert fast == pytest.approx(general, rel=1e-12, abs=1e-12), m


@pytest.mark.parametrize("per_pass", [1, 2, 3, 8])
def test_levels_sharing_a_pass_give_the_definitions(monkeypatch: pytest.MonkeyPatch, per_pass: int) -> None:
    """Several octave levels in one pass (each a chunk behind the previous), on an odd length whose last levels
    end inside a chunk and have fewer chunks than the first."""
    monkeypatch.setattr(al, "LEVELS_PER_PASS", per_pass)
    n = 2999
    y = _record(n, 13)
    res = allan_variances(y, 1.0, "octave", chunk=64)
    assert list(res.m) == [1, 2, 4, 8, 16, 32, 64, 128, 256, 512]
    for j, m in enumerate(res.m):
        ref = _definitions(y, int(m))
        for est in ESTIMATORS:
            assert res.var[est][j, 0] == pytest.approx(ref[est], rel=1e-10), (est, int(m))


@pytest.mark.parametrize("n", [1000, 1001, 1037])
@pytest.mark.parametrize("m", [16, 24, 48, 128, 250])
def test_column_walk_equals_the_chunk_walk(n: int, m: int) -> None:
    """m ≥ chunk: the column-by-column pass (shared first differences and pair sums) gives the sums and the
    doubled G of the plain chunk-by-chunk pass, for blocks cut by the period, the record's end and the chunk."""
    rng = np.random.default_rng(n + m)
    x = np.concatenate([[0.0], np.cumsum(rng.normal(size=n))])
    g0 = np.append(np.diff(x), 0.0)  # stands for G_m: the passes do not depend on what G holds
    chunk = 16
    ga, gb = g0.copy(), g0.copy()
    bufs = al._Buffers(chunk, 2 * chunk)
    ref = al.octave_levels(x, ga, [(m, n // m - 1, True)], chunk, bufs)[0]
    t1 = al.lag_sum(g0, m, n + 2 - 3 * m) if n + 2 - 3 * m > 0 else 0.0
    far = al.octave_far(x, gb, m, n // m - 1, True, chunk, bufs)
    np.testing.assert_allclose(far[:3], ref[:3], rtol=1e-12)
    assert far[3] == pytest.approx(t1, rel=1e-12, abs=1e-12) and ref[3] == pytest.approx(t1, rel=1e-12, abs=1e-12)
    top = max(n + 2 - 4 * m, 0)
    np.testing.assert_allclose(gb[:top], ga[:top], rtol=1e-12, atol=1e-12)
    np.testing.assert_array_equal(gb[top:], g0[top:])  # beyond the doubled range: untouched


@pytest.mark.parametrize("k", [1, 2, 3, 255, 256, 257, 1000, 4097, 65536])
@pytest.mark.parametrize("depth", [0, 1, 4])
def test_pairwise_prefix_sum_equals_the_cumulative_sum(k: int, depth: int) -> None:
    rng = np.random.default_rng(k + depth)
    v = rng.normal(size=k) + 50.0
    out = np.full(2 * k, np.nan)
    al.prefix_sum(v, out[::2], np.empty(k), depth)  # into a strided view, as the recursion does
    ref = np.cumsum(v.astype(np.longdouble))
    np.testing.assert_allclose(out[::2], ref.astype(np.float64), rtol=1e-12)
    assert np.isnan(out[1::2]).all()  # nothing written outside the view


def test_blocked_dot_without_vecdot(monkeypatch: pytest.MonkeyPatch) -> None:
    """numpy < 2.0 has no vecdot: the blocks are then summed by einsum, same values."""
    v = np.random.default_rng(3).normal(size=6 * 4096 + 18)
    with_vecdot = al.sum_of_products(v)
    monkeypatch.setattr(al, "vecdot", None)
    assert al.sum_of_products(v) == pytest.approx(with_vecdot, rel=1e-13)
    assert al.sum_of_products(v[::2], v[1::2]) == pytest.approx(float(v[::2] @ v[1::2]), rel=1e-12, abs=1e-12)

"""The recording's raw time sources (/timing): the clock columns stored as integer nanosecond deltas read back
to within half a nanosecond (NaN kept), across checkpoints and a resume; recordings that hold them as float64
(written before the encoding) still read and resume unchanged (benches/RECORDING.md, "/timing")."""

from __future__ import annotations

import h5py  # only to inspect the stored encoding and to write the older layout
import numpy as np
import pytest

from benches.recording import Hdf5Recorder, StepRecord, open_recording
from benches.recording.encoding import ns_delta_decode, ns_delta_encode
from benches.recording.layout import NS_NAN, TIMING_CLOCKS
from drivers.protocols import ImuBlock, TableState, TableStatus

BLOCK = 50
READS_PER_STEP = 30


def _clocks(n: int, seed: int) -> dict[str, np.ndarray]:
    """Clock readings of n table readings (s): a host clock with jitter, a controller clock 20 ppm off with an
    offset, NaN where a source was not known (as a real link has)."""
    rng = np.random.default_rng(seed)
    t = 1234.5 + np.arange(n) * 0.2 + rng.uniform(0, 3e-3, n)
    out = {
        "table_host_request": t,
        "table_host_answer": t + rng.uniform(2e-3, 6e-3, n),
        "table_controller_time": 0.0173 + (1 + 20e-6) * (t + 2.5e-3),
        "block_host_time": t - rng.uniform(0, 1e-3, n),
    }
    out["table_controller_time"][[0, 7, 8]] = np.nan
    out["table_host_answer"][n - 1] = np.nan
    return out


def _write(path, clocks: dict[str, np.ndarray], steps: range, resume: bool = False) -> None:
    rec = Hdf5Recorder(path, attrs={"sample_rate_hz": 100.0}, resume=resume, checkpoint_samples=10**9)
    for k in steps:
        for j in range(READS_PER_STEP):
            i = k * READS_PER_STEP + j
            idx = np.arange(i * BLOCK, (i + 1) * BLOCK)
            z = np.zeros((BLOCK, 3))
            blk = ImuBlock(idx.astype(np.uint32), idx / 100.0, z, z, np.full(BLOCK, 300.0),
                           np.zeros(BLOCK, np.uint16), host_time=float(clocks["block_host_time"][i]))  # fmt: skip
            rec.add_samples(blk)
            reading = TableState(float(i), np.zeros(3), np.zeros(3), TableStatus.IN_POSITION,
                                 controller_time=float(clocks["table_controller_time"][i]),
                                 host_request=float(clocks["table_host_request"][i]),
                                 host_answer=float(clocks["table_host_answer"][i]))  # fmt: skip
            rec.add_table(reading)
        n0, t0 = k * READS_PER_STEP * BLOCK, k * READS_PER_STEP
        n1, t1 = n0 + READS_PER_STEP * BLOCK, t0 + READS_PER_STEP
        rec.end_step(
            StepRecord(k, f"hold-{k}", "hold", "A", n0, n0, n1, n1, "complete", table_start=t0, table_end=t1)
        )  # a checkpoint per step: the deltas continue across appends
    rec.set_status("interrupted" if not resume else "complete")
    rec.close()


def _read(path) -> dict[str, np.ndarray]:
    with open_recording(path) as rec:
        tim = rec.timing()
    assert tim is not None
    return {name: getattr(tim, name) for name in TIMING_CLOCKS}


def _assert_close(got: dict[str, np.ndarray], want: dict[str, np.ndarray], n: int) -> None:
    for name in TIMING_CLOCKS:
        g, w = got[name], want[name][:n]
        assert g.shape == (n,)
        np.testing.assert_array_equal(np.isnan(g), np.isnan(w), err_msg=name)
        ok = ~np.isnan(w)
        assert np.max(np.abs(g[ok] - w[ok])) <= 0.5e-9 + 4e-16 * np.max(np.abs(w[ok])), name


def test_the_encoding_round_trips_nans_and_continues_from_the_last_value():
    v = np.array([np.nan, 10.0, 10.25, np.nan, 9.5, np.inf, 1e6 + 1e-9])
    a, last = ns_delta_encode(v[:3], 0)
    b, last = ns_delta_encode(v[3:], last)
    stored = np.concatenate([a, b])
    assert stored[0] == NS_NAN and stored[3] == NS_NAN and stored[5] == NS_NAN  # NaN (and any non-finite): none
    assert stored[2] == 250_000_000 and stored[4] == -750_000_000  # deltas from the previous value read
    back = ns_delta_decode(stored)
    np.testing.assert_array_equal(np.isnan(back), [True, False, False, True, False, True, False])
    np.testing.assert_allclose(back[[1, 2, 4, 6]], v[[1, 2, 4, 6]], rtol=0, atol=1e-9)
    assert last == round(v[6] * 1e9)


def test_clock_columns_are_stored_as_ns_deltas_and_read_back(tmp_path):
    path = tmp_path / "recording.h5"
    clocks = _clocks(3 * READS_PER_STEP, 1)
    _write(path, clocks, range(3))
    with h5py.File(path, "r") as f:
        for name in TIMING_CLOCKS:
            d = f["timing"][name]
            assert d.dtype == np.int64 and d.attrs["encoding"] == b"ns-delta"
    _assert_close(_read(path), clocks, 3 * READS_PER_STEP)


def test_resume_continues_the_deltas(tmp_path):
    path = tmp_path / "recording.h5"
    clocks = _clocks(4 * READS_PER_STEP, 2)
    _write(path, clocks, range(2))
    _write(path, clocks, range(2, 4), resume=True)
    _assert_close(_read(path), clocks, 4 * READS_PER_STEP)


def _as_older_layout(path) -> dict[str, np.ndarray]:
    """Rewrite the clock columns the way recordings made before the encoding hold them (float64, no attribute)."""
    vals = _read(path)
    with h5py.File(path, "r+") as f:
        g = f["timing"]
        for name in TIMING_CLOCKS:
            chunks, filters = g[name].chunks, {"compression": "gzip", "shuffle": True, "fletcher32": True}
            del g[name]
            g.create_dataset(name, data=vals[name], maxshape=(None,), chunks=chunks, **filters)
    return vals


@pytest.mark.parametrize("resume", [False, True])
def test_recordings_with_float_clock_columns_still_read_and_resume(tmp_path, resume):
    path = tmp_path / "recording.h5"
    clocks = _clocks(4 * READS_PER_STEP, 3)
    _write(path, clocks, range(2))
    old = _as_older_layout(path)
    got = _read(path)
    for name in TIMING_CLOCKS:  # read exactly as stored
        np.testing.assert_array_equal(got[name], old[name])
    if resume:  # a resumed older recording keeps its float64 columns
        _write(path, clocks, range(2, 4), resume=True)
        with h5py.File(path, "r") as f:
            assert all(f["timing"][n].dtype == np.float64 for n in TIMING_CLOCKS)
        got = _read(path)
        for name in TIMING_CLOCKS:
            np.testing.assert_array_equal(got[name][2 * READS_PER_STEP :], clocks[name][2 * READS_PER_STEP :])

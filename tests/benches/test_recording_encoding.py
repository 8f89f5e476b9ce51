"""The recorder encodes /imu chunks itself (shuffle → deflate → Fletcher-32 in a worker thread): the bytes must
be what HDF5's own filters produce and decode, checked here against the library."""

from __future__ import annotations

import itertools

import h5py  # the reference: HDF5's own filter pipeline
import numpy as np

from benches.recording import _encode_chunk, _fletcher32


def test_fletcher32_equals_hdf5s_for_every_length_and_extreme_bytes(tmp_path):
    rng = np.random.default_rng(0)
    with h5py.File(tmp_path / "f.h5", "w") as f:
        sizes = (*range(1, 80), 359, 360, 361, 719, 720, 721, 131_071, 131_072, 131_073, 131_074, 300_001, 4_200_001)
        cases = [rng.integers(0, 256, n).astype("u1") for n in sizes]  # (> 2¹⁷ bytes: several blocks of 2¹⁶ words)
        cases += [np.full(100_000, 255, "u1"), np.zeros(4097, "u1"), np.full(7201, 0x80, "u1")]
        cases += [np.full(n, 255, "u1") for n in (131_072, 131_073, 4_200_001)]  # the largest sums, several blocks
        for k, data in enumerate(cases):
            d = f.create_dataset(f"d{k}", data=data, chunks=(data.size,), fletcher32=True)
            _mask, stored = d.id.read_direct_chunk((0,))
            assert _fletcher32(stored[:-4]).to_bytes(4, "little") == stored[-4:], data.size


def test_encoded_chunks_decode_through_hdf5(tmp_path):
    rng = np.random.default_rng(1)
    with h5py.File(tmp_path / "e.h5", "w") as f:
        for (dt, width), rle in itertools.product(
            (("i4", 3), ("i8", None), ("f8", None), ("u2", None), ("u4", None), ("f8", 3)), (False, True)
        ):
            shape = (0,) if width is None else (0, width)
            d = f.create_dataset(
                f"{dt}{width}{rle}", shape=shape, maxshape=(None, *shape[1:]), chunks=(1000, *shape[1:]), dtype=dt,
                fletcher32=True, shuffle=True, compression="gzip", compression_opts=1,
            )  # fmt: skip
            n = 2537
            data = rng.normal(0, 1e4, (n, *shape[1:])).astype(dt)
            d.resize(n, axis=0)
            for r0 in range(0, n, 1000):
                buf = np.zeros((1000, *shape[1:]), dt)
                buf[: min(1000, n - r0)] = data[r0 : r0 + 1000]
                d.id.write_direct_chunk((r0,) + (0,) * (len(shape) - 1), _encode_chunk(buf, rle), 0)
            np.testing.assert_array_equal(d[()], data)

"""Issue 12 item 2: a recording with flipped bytes (data or metadata) gives exit 2 and one clear line in every
command — or, where the flip hit unused bytes, exactly the original results; never a traceback, never other
numbers with exit 0, never a PASS. A recording from another tool without checksums stays usable and says that
its integrity cannot be verified."""

from __future__ import annotations

import json
import shutil

import h5py  # tests craft and damage files directly; only benches/recording/ uses h5py in the package
import numpy as np
import pytest

from benches.cli import main
from benches.recording import RecordingError, open_recording
from tests.simbench import bench_variant, short_ten_step

SHORT = short_ten_step(hold_s=2, warmup_s=20)


@pytest.fixture(scope="module")
def pristine(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("integrity")
    bench = bench_variant(tmp, rate=50.0)
    proc = tmp / "short.yaml"
    proc.write_text(SHORT, encoding="utf-8")
    run = tmp / "runs" / "orig"
    argv = ["run", "--bench", str(bench), "--procedure", str(proc), "--seed", "2", "--plain", "--out", str(run)]
    assert main(argv) == 0
    return run


def _dump(path) -> list:
    """Everything the reader gives, as comparable bytes/text."""
    with open_recording(path) as rec:
        smp, tab = rec.samples(), rec.table()
        truth = rec.truth()
        return [
            repr(rec.header),
            [repr(s) for s in rec.steps],
            [getattr(smp, n).tobytes() for n in ("counter", "time", "accel", "gyro", "temperature", "status")],
            [getattr(tab, n).tobytes() for n in ("time", "angles", "rates", "status")],
            [repr(e) for e in rec.events()],
            rec.bench_text,
            rec.procedure_text,
            None if truth is None else (repr(truth.parameters), [a.tobytes() for a in truth.arrays.values()]),
            rec.integrity_verified,
        ]


def _flip(src, dst, offset: int) -> None:
    data = bytearray(src.read_bytes())
    data[offset] ^= 0xFF
    dst.write_bytes(bytes(data))


def _offsets(path, n: int) -> list[int]:
    size = path.stat().st_size
    head = list(range(0, min(size, 2048), 13))  # superblock and the root object header: dense
    return sorted(set(head + np.linspace(2048, size - 1, n).astype(int).tolist()))


def _sweep(pristine, tmp_path, n: int) -> tuple[int, int]:
    rec = pristine / "recording.h5"
    ref = _dump(rec)
    damaged = unchanged = 0
    bad = tmp_path / "flipped.h5"
    for off in _offsets(rec, n):
        _flip(rec, bad, off)
        try:
            got = _dump(bad)
        except RecordingError as exc:
            msg = str(exc)
            assert "\n" not in msg and str(bad) in msg, (off, msg)
            damaged += 1
            continue
        assert got == ref, f"byte {off}: the reader returned different content without an error"
        unchanged += 1
    return damaged, unchanged


def test_flipped_bytes_are_detected_or_harmless(pristine, tmp_path):
    damaged, unchanged = _sweep(pristine, tmp_path, 250)
    assert damaged > 0.5 * (damaged + unchanged)  # most bytes of a compressed, checksummed file matter


@pytest.mark.slow
def test_flipped_bytes_at_many_more_offsets(pristine, tmp_path):
    damaged, unchanged = _sweep(pristine, tmp_path, 5000)
    assert damaged > 0


def _chunk_offset(path, dataset: str) -> int:
    with h5py.File(path, "r") as f:
        d = f[dataset]
        info = d.id.get_chunk_info(0)
        return int(info.byte_offset + info.size // 2)


def _commands(run, tmp_path) -> list[list[str]]:
    return [
        ["identify", str(run), "--out", str(tmp_path / "cal.json")],
        ["certificate", str(run), "--out", str(tmp_path / "cert.pdf")],
        ["run", "--resume", str(run)],
        ["noise", str(run), "--channels", "accel_z", "--taus", "octave"],
        ["periodic", str(run), "--channels", "accel_z", "--terms", "1"],
        ["drift", str(run), "--channels", "accel_z", "--quiet"],
        ["correct", str(run / "calibration.json"), str(run), "--out", str(tmp_path / "c.npy")],
        ["runs", str(run.parent)],
    ]


TARGETS = ["/imu/accel", "/imu/time", "/table/angles", "/steps", "/events", "/bench_yaml", "superblock", "root"]


@pytest.mark.parametrize("target", TARGETS)
def test_every_command_says_one_line_and_exits_2_on_a_damaged_recording(pristine, tmp_path, capsys, target):
    run = tmp_path / "runs" / "dmg"
    shutil.copytree(pristine, run)
    rec = run / "recording.h5"
    off = {"superblock": 20, "root": 0x40}.get(target) or _chunk_offset(rec, target)
    _flip(pristine / "recording.h5", rec, off)
    with pytest.raises(RecordingError):
        open_recording(rec)
    capsys.readouterr()
    for argv in _commands(run, tmp_path):
        rc = main(argv)
        out = capsys.readouterr()
        lines = [ln for ln in out.err.splitlines() if "error" in ln]
        assert rc == 2, (argv, out.err[-500:])
        assert len(lines) == 1 and "recording.h5" in out.err and "Traceback" not in out.err, (argv, out.err)
        assert "PASS" not in out.out + out.err
    assert not (tmp_path / "cert.pdf").exists() and not (tmp_path / "cal.json").exists()


def test_identification_of_an_undamaged_copy_gives_the_same_numbers(pristine, tmp_path, capsys):
    run = tmp_path / "copy"
    shutil.copytree(pristine, run)
    assert main(["identify", str(run), "--out", str(tmp_path / "cal.json")]) == 0
    a = json.loads((pristine / "calibration.json").read_text(encoding="utf-8"))
    b = json.loads((tmp_path / "cal.json").read_text(encoding="utf-8"))
    assert a["parameters"] == b["parameters"] and a["covariance"] == b["covariance"]


def test_a_recording_without_checksums_is_usable_and_says_so(pristine, tmp_path, capsys):
    """Format version 1, as another tool writes it from RECORDING.md: no filters, vlen strings."""
    src = pristine / "recording.h5"
    dst = tmp_path / "foreign" / "recording.h5"
    dst.parent.mkdir()
    with open_recording(src) as rec:
        smp, tab, steps, hdr = rec.samples(), rec.table(), rec.steps, rec.header
        bench_text = rec.bench_text
    with h5py.File(dst, "w") as f:
        f.attrs.update(format="tablebench-recording", format_version=1, sample_rate_hz=hdr.sample_rate_hz)
        f.attrs.update(status="complete", bench_name=hdr.bench_name, procedure_name=hdr.procedure_name, seed=-1)
        f["bench_yaml"] = bench_text
        for n in ("counter", "time", "accel", "gyro", "temperature", "status"):
            f[f"imu/{n}"] = getattr(smp, n)
        for n in ("time", "angles", "rates", "status"):
            f[f"table/{n}"] = getattr(tab, n)
        s = h5py.string_dtype()
        dt = [("index", "i4"), ("name", s), ("kind", s), ("group", s), ("start_sample", "i8"), ("acq_start", "i8")]
        dt += [("acq_end", "i8"), ("end_sample", "i8"), ("status", s), ("axis", "i1"), ("rate", "f8")]
        dt += [("angles", "f8", (3,))]
        rows = [
            (x.index, x.name, x.kind, x.group, x.start_sample, x.acq_start, x.acq_end, x.end_sample, x.status)
            + (x.axis, x.rate, x.angles)
            for x in steps
        ]
        f["steps"] = np.array(rows, dtype=dt)
    with open_recording(dst) as rec:
        assert not rec.integrity_verified and "cannot be verified" in rec.integrity_note
    capsys.readouterr()
    assert main(["identify", str(dst.parent)]) == 0
    cal = json.loads((dst.parent / "calibration.json").read_text(encoding="utf-8"))
    assert cal["run"]["integrity_verified"] is False and "cannot be verified" in cal["run"]["integrity_note"]
    assert main(["noise", str(dst.parent), "--channels", "accel_z", "--taus", "octave"]) == 0
    assert "integrity cannot be verified" in capsys.readouterr().err


def test_an_hdf5_file_that_is_not_a_recording_or_of_another_version_is_one_line(tmp_path, capsys):
    other = tmp_path / "other.h5"
    with h5py.File(other, "w") as f:
        f["x"] = np.arange(10.0)
    newer = tmp_path / "newer.h5"
    with h5py.File(newer, "w") as f:
        f.attrs.update(format="tablebench-recording", format_version=99, sample_rate_hz=100.0)
        f["imu/accel"] = np.zeros((100, 3))
    for path, words in ((other, "not a tablebench recording"), (newer, "format version 99")):
        for cmd in ("noise", "drift", "periodic", "identify"):
            assert main([cmd, str(path)]) == 2
            err = capsys.readouterr().err
            assert len(err.strip().splitlines()) == 1 and words in err and "Traceback" not in err, (cmd, err)
    assert main(["runs", str(tmp_path / "nonexistent")]) == 2
    assert len(capsys.readouterr().err.strip().splitlines()) == 1


def test_index_reads_from_the_verified_rows_equal_the_files(pristine, tmp_path):
    """Issue 32: a fancy-index read inside an acquisition window is served from the rows the verifying pass
    kept; it must give exactly what decoding the file gives (every field, quantised or not)."""
    copy = tmp_path / "copy.h5"
    shutil.copy(pristine / "recording.h5", copy)
    with open_recording(copy, verify=False) as raw, open_recording(copy) as kept:
        assert kept._kept, "the verifying pass keeps the acquisition windows"
        for s in kept.complete_steps():
            if s.acq_end - s.acq_start < 3:
                continue
            idx = np.array([s.acq_start, (s.acq_start + s.acq_end) // 2, s.acq_end - 1])
            for name in ("time", "accel", "gyro", "status", "temperature"):
                a = getattr(raw.samples(fields=(name,), index=idx), name)
                b = getattr(kept.samples(fields=(name,), index=idx), name)
                assert a.dtype == b.dtype and np.array_equal(a, b), (s.name, name)


def test_the_chunk_index_is_read_in_one_pass_as_entry_by_entry(tmp_path):
    """The layout check's chunk index (benches.recording.reader._chunk_infos): one pass over the index gives every
    entry get_chunk_info(i) gives, in the same order (offsets, filter masks, sizes), and without chunk_iter the
    entry-by-entry lookup is what it falls back to."""
    from benches.recording.reader import _chunk_infos

    path = tmp_path / "chunks.h5"
    with h5py.File(path, "w") as f:
        f.create_dataset("a", data=np.arange(30000.0).reshape(-1, 3), chunks=(512, 3), fletcher32=True)
        f.create_dataset("b", data=np.arange(7, dtype=np.int32), chunks=(4,), fletcher32=True, maxshape=(None,))
        f.create_dataset("c", shape=(0, 3), dtype="f8", chunks=(16, 3), maxshape=(None, 3), fletcher32=True)
    with h5py.File(path, "r") as f:
        for name in ("a", "b", "c"):
            d = f[name]
            want = [d.id.get_chunk_info(i) for i in range(d.id.get_num_chunks())]
            got = _chunk_infos(d)
            key = [(tuple(i.chunk_offset), i.filter_mask, i.byte_offset, i.size) for i in want]
            assert [(tuple(i.chunk_offset), i.filter_mask, i.byte_offset, i.size) for i in got] == key, name

            class _NoIter:  # a dataset whose h5py has no chunk_iter
                id = type("Id", (), {"get_num_chunks": d.id.get_num_chunks, "get_chunk_info": d.id.get_chunk_info})()

            assert [(tuple(i.chunk_offset), i.size) for i in _chunk_infos(_NoIter())] == [(k[0], k[3]) for k in key]

"""The live view's parts without a browser: the feed, the decimator, the observer on a real run, the server's
routes (read-only, Last-Event-ID, results only), the address rules and ``view`` on a finished run."""

from __future__ import annotations

import json
import socket
import subprocess
import sys
import urllib.error
import urllib.request
from pathlib import Path

import numpy as np
import pytest

from benches.live.feed import LiveFeed, MinMaxDecimator
from benches.live.replay import LIVE_FILE, JsonlFollower, feed_from_recording
from benches.live.server import DEFAULT_HOST, DEFAULT_PORT, LiveServer, check_free, parse_address
from core.errors import UsageError
from tests.simbench import CLI, bench_variant, short_ten_step


# ---- feed and decimator ------------------------------------------------------------------------------------------
def test_feed_replays_everything_after_an_id(tmp_path: Path) -> None:
    feed = LiveFeed(tmp_path / "live.jsonl")
    for k in range(5):
        feed.publish("step", {"index": k})
    assert [e.id for e in feed.since(0)] == [1, 2, 3, 4, 5]
    assert [e.data["index"] for e in feed.since(3)] == [3, 4]
    feed.close()
    lines = (tmp_path / "live.jsonl").read_text(encoding="utf-8").splitlines(keepends=True)
    again = LiveFeed.from_lines(lines + ['{"id": 6, "event": "st'])  # a partial last line is not taken
    assert [(e.id, e.kind, e.data) for e in again.events()] == [(e.id, e.kind, e.data) for e in feed.events()]


def test_feed_refuses_non_finite_numbers_in_its_file(tmp_path: Path) -> None:
    feed = LiveFeed(tmp_path / "live.jsonl")
    feed.publish("bins", {"x": float("nan")})  # kept in memory; left out of the file (strict JSON only)
    feed.publish("bins", {"x": 1.0})
    feed.close()
    lines = (tmp_path / "live.jsonl").read_text(encoding="utf-8").splitlines()
    assert [json.loads(line, parse_constant=float.fromhex) for line in lines] == [
        {"id": 2, "event": "bins", "data": {"x": 1.0}}
    ]


@pytest.mark.parametrize("chunk", [1, 7, 200])
def test_decimator_is_min_and_max_per_bin_whatever_the_blocks(chunk: int) -> None:
    rng = np.random.default_rng(3)
    t = np.arange(0.0, 50.0, 0.01)
    x = rng.normal(size=(t.size, 3))
    dec = MinMaxDecimator(3, 0.25, max_bins=64)  # 200 bins of data → merged twice
    for i in range(0, t.size, chunk):
        dec.add(t[i : i + chunk], x[i : i + chunk])
    dec.flush()
    assert dec.bin_s == 1.0 and len(dec) == 50
    idx = np.floor(t / dec.bin_s).astype(int)
    for k in range(len(dec)):
        np.testing.assert_array_equal(dec.lo[k], x[idx == k].min(axis=0))
        np.testing.assert_array_equal(dec.hi[k], x[idx == k].max(axis=0))


# ---- addresses ----------------------------------------------------------------------------------------------------
def test_addresses() -> None:
    assert parse_address(None) == parse_address("") == (DEFAULT_HOST, DEFAULT_PORT) == ("127.0.0.1", 8765)
    assert parse_address("8800") == ("127.0.0.1", 8800)
    assert parse_address("0.0.0.0:9000") == ("0.0.0.0", 9000)
    assert parse_address("[::1]:9001") == ("::1", 9001)
    for bad in ("http", "70000", "host:", ":0"):
        with pytest.raises(UsageError, match=r"--live .*\[HOST:\]PORT"):
            parse_address(bad)


def test_a_port_in_use_is_refused_before_anything_moves() -> None:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        s.listen()
        port = s.getsockname()[1]
        with pytest.raises(UsageError, match=f"127.0.0.1:{port}: cannot serve there .*choose another port"):
            check_free("127.0.0.1", port)


# ---- server routes ------------------------------------------------------------------------------------------------
class _Client:
    """HTTP against a real LiveServer on a free port (what a browser talks to)."""

    def __init__(self, feed: LiveFeed, folder: Path | None = None) -> None:
        self.server = LiveServer(feed, "127.0.0.1", 0, run_folder=folder)

    def __enter__(self) -> _Client:
        self.server.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.server.close()

    def request(self, method: str, path: str, headers: dict[str, str] | None = None) -> tuple[int, bytes]:
        req = urllib.request.Request(self.server.url.rstrip("/") + path, method=method.upper(), headers=headers or {})
        try:
            with urllib.request.urlopen(req, timeout=10) as r:
                return r.status, r.read()
        except urllib.error.HTTPError as exc:
            return exc.code, exc.read()

    def text(self, path: str, headers: dict[str, str] | None = None) -> str:
        status, body = self.request("GET", path, headers)
        assert status == 200, (path, status)
        return body.decode("utf-8")


def _ids(body: str) -> list[int]:
    return [int(line[4:]) for line in body.splitlines() if line.startswith("id: ")]


def test_events_resume_after_last_event_id() -> None:
    feed = LiveFeed()
    for k in range(5):
        feed.publish("step", {"index": k})
    feed.close()
    with _Client(feed) as c:
        body = c.text("/events", headers={"Last-Event-ID": "3"})
        assert body.startswith("retry: ") and _ids(body) == [4, 5]
        body = c.text("/events")
        assert _ids(body) == [1, 2, 3, 4, 5]
        assert 'event: step\ndata: {"index":0}' in body
        assert _ids(c.text("/events?last=4")) == [5]  # a page that reconnects by itself says where it was


def test_the_server_is_read_only_and_serves_only_results(tmp_path: Path) -> None:
    feed = LiveFeed()
    feed.close()
    (tmp_path / "calibration.json").write_text("{}", encoding="utf-8")
    (tmp_path / "recording.h5").write_bytes(b"\x89HDF")
    with _Client(feed, tmp_path) as c:
        page = c.text("/")
        assert "at the bench" in page and "Ctrl-C" in page
        assert "http" not in page  # every asset is local: no CDN
        assert c.request("GET", "/static/uPlot.iife.min.js")[0] == 200
        assert c.request("GET", "/static/server.py")[0] == 404
        assert json.loads(c.text("/files/calibration.json")) == {}
        assert c.request("GET", "/files/recording.h5")[0] == 404
        assert c.request("GET", "/files/certificate.pdf")[0] == 404  # not there yet
        for path in ("/", "/events", "/files/calibration.json", "/static/live.js"):
            for method in ("post", "put", "delete", "patch"):
                assert c.request(method, path)[0] == 405, (method, path)


def test_live_page_assets_are_vendored() -> None:
    static = Path(__file__).resolve().parents[2] / "benches" / "live" / "static"
    for name in ("index.html", "live.js", "live.css", "uPlot.iife.min.js", "uPlot.min.css", "LICENSE.uPlot"):
        assert (static / name).is_file(), name
    assert "cdn" not in (static / "index.html").read_text(encoding="utf-8").lower()


# ---- a real run: its live file, and view of the finished run ------------------------------------------------------
@pytest.fixture(scope="module")
def finished_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    tmp = tmp_path_factory.mktemp("live")
    bench = bench_variant(tmp, rate=100.0)
    proc = tmp / "short.yaml"
    proc.write_text(short_ten_step(hold_s=2, warmup_s=5, name="short"), encoding="utf-8")
    out = tmp / "run"
    r = subprocess.run(
        CLI + ["run", "--bench", str(bench), "--procedure", str(proc), "--out", str(out), "--plain", "--seed", "5"],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert r.returncode == 0, r.stderr[-2000:]
    return out


def test_every_run_writes_its_live_file(finished_run: Path) -> None:
    follower = JsonlFollower(finished_run / LIVE_FILE)
    events = list(follower.feed.events())
    assert follower.feed.closed  # the result came: nothing more to follow
    kinds = [e.kind for e in events]
    assert kinds[0] == "run" and kinds[-1] == "result" and "end" in kinds and "estimates" in kinds
    run = events[0].data
    done = [e.data["index"] for e in events if e.kind == "step" and e.data["state"] == "complete"]
    assert done == [s["index"] for s in run["steps"]]  # every step ends, once, in order
    cal = json.loads((finished_run / "calibration.json").read_text(encoding="utf-8"))
    result = events[-1].data
    assert [p["name"] for p in result["parameters"]] == list(cal["parameters"])
    assert [p["value"] for p in result["parameters"]] == [p["display_value"] for p in cal["parameters"].values()]
    assert "calibration.json" in result["files"] and "certificate.pdf" in result["files"]
    # the channels: one min/max column per bin, never more than the decimator's cap, all finite
    bins = [e.data for e in events if e.kind == "bins"]
    n_cols = max(b["start"] + len(b["lo"]) for b in bins)
    assert 0 < n_cols <= 2400
    assert all(all(v is not None for row in b["lo"] for v in row) for b in bins)


def test_view_of_a_finished_recording_without_live_file(finished_run: Path, tmp_path: Path) -> None:
    folder = tmp_path / "old"
    folder.mkdir()
    for name in ("recording.h5", "calibration.json", "certificate.json"):
        (folder / name).write_bytes((finished_run / name).read_bytes())
    feed = feed_from_recording(folder)
    kinds = [e.kind for e in feed.events()]
    assert kinds[0] == "run" and kinds[-1] == "result" and feed.closed
    live = [e for e in JsonlFollower(finished_run / LIVE_FILE).feed.events() if e.kind == "step"]
    replayed = [e for e in feed.events() if e.kind == "step"]
    assert [(e.data["index"], e.data["state"]) for e in replayed if e.data["state"] != "running"] == [
        (e.data["index"], e.data["state"]) for e in live if e.data["state"] != "running"
    ]


def test_view_and_run_refuse_bad_input_in_one_line(tmp_path: Path) -> None:
    r = subprocess.run(CLI + ["view", str(tmp_path)], capture_output=True, text=True, timeout=60)
    assert r.returncode == 2 and "neither live.jsonl nor recording.h5" in r.stderr and "Traceback" not in r.stderr
    r = subprocess.run(CLI + ["run", "--live", "nohost:x", "--out", str(tmp_path / "r")], capture_output=True,
                       text=True, timeout=60)  # fmt: skip
    assert r.returncode == 2 and "[HOST:]PORT" in r.stderr and len(r.stderr.strip().splitlines()) == 1
    assert not (tmp_path / "r").exists()  # refused before anything was created or moved


def test_help_names_the_default_address() -> None:
    r = subprocess.run(CLI + ["run", "--help"], capture_output=True, text=True, timeout=60)
    assert "127.0.0.1:8765" in r.stdout and sys.executable

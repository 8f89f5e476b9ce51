"""``tablebench view``'s sources: a run's ``live.jsonl`` (followed while the run goes on), or its recording.

A run writes its live events to ``RUN/live.jsonl`` as it goes; :class:`JsonlFollower` reads that file into a
:class:`~benches.live.feed.LiveFeed` and keeps reading what the running process appends, so a second
terminal (or another machine, with ``--live 0.0.0.0:PORT``) can watch a run it did not start. A finished
recording without that file (older runs) is replayed through the same observer from the recording itself
(the one reader, ``benches.recording``) and calibration.json.
"""

from __future__ import annotations

import json
import threading
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import numpy as np

from analysis.units import DISPLAY_UNITS
from benches.recording import open_recording
from drivers.protocols import TableState, TableStatus

from .feed import LiveFeed
from .observer import LiveObserver, publish_result

LIVE_FILE = "live.jsonl"
"""The live events of a run, next to its recording (one JSON object a line)."""


class JsonlFollower:
    """Follow ``RUN/live.jsonl`` into a feed until the run's ``result`` (or ``end`` without results) arrives.

    Parameters
    ----------
    path : Path
        The live file.
    poll_s : float
        How often the file is read for new lines.
    """

    def __init__(self, path: Path, poll_s: float = 0.5) -> None:
        self.path = path
        self.feed = LiveFeed()
        self.poll_s = poll_s
        self._pos = 0
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._loop, name="tablebench-follow", daemon=True)
        self.read_new()

    def read_new(self) -> int:
        """Take the complete lines appended since the last read; returns how many events were added."""
        try:
            with open(self.path, encoding="utf-8") as f:
                f.seek(self._pos)
                lines = f.readlines()
        except OSError:
            return 0
        taken = self.feed.extend_lines(lines)
        self._pos += sum(len(line.encode("utf-8")) for line in lines[:taken])
        for ev in self.feed.since(len(self.feed) - taken):
            if ev.kind == "result":
                self.feed.close()
        return taken

    def start(self) -> JsonlFollower:
        """Keep following in a background thread."""
        if not self.feed.closed:
            self._thread.start()
        return self

    def _loop(self) -> None:
        while not self._stop.wait(self.poll_s) and not self.feed.closed:
            self.read_new()

    def stop(self) -> None:
        """Stop following."""
        self._stop.set()


def feed_from_recording(folder: Path, columns_hint: float | None = None) -> LiveFeed:
    """A closed feed built from a finished recording (and its calibration.json / certificate) in ``folder``."""
    feed = LiveFeed()
    cal = _calibration(folder)
    with open_recording(folder / "recording.h5") as rec:
        h = rec.header
        rate = float(h.sample_rate_hz)
        steps = [SimpleNamespace(**{k: getattr(s, k) for k in ("index", "name", "kind", "group", "axis", "rate")},
                                 angles=tuple(s.angles), text="") for s in rec.steps]  # fmt: skip
        total = rec.n_samples / rate
        obs = LiveObserver(
            feed,
            steps,  # type: ignore[arg-type]
            sample_rate=rate,
            estimated_s=columns_hint or total,
            info={
                "bench": h.bench_name,
                "procedure": h.procedure_name,
                "run_folder": str(folder),
                "status": h.status,
                "source": "recording",
                "parameters": _parameters(cal),
            },  # fmt: skip
            publish_s=0.0,
        )
        table = rec.table()
        for s, step in zip(rec.steps, steps, strict=True):
            for chunk in rec.iter_samples(s.start_sample, s.end_sample, fields=("accel", "gyro", "time")):
                t_end = float(chunk.time[-1]) if len(chunk) else 0.0
                k = int(np.searchsorted(table.time, t_end, side="right")) - 1
                state = _state(table, max(k, 0)) if len(table) else None
                obs.on_block(step, _Block(chunk.accel, chunk.gyro), state, True)  # type: ignore[arg-type]
            obs.on_step_end(step, SimpleNamespace(status=s.status))  # type: ignore[arg-type]
        obs.finish(h.status)
    _history_estimates(feed, cal)
    publish_result(feed, folder)
    feed.close()
    return feed


class _Block:
    """An ``ImuBlock``-shaped view of recorded samples (the observer reads accel, gyro and link counters)."""

    def __init__(self, accel: np.ndarray, gyro: np.ndarray) -> None:
        self.accel, self.gyro = accel, gyro
        self.rejected = self.dropped = self.resets = self.duplicates = 0
        self.events: list[str] = []

    def __len__(self) -> int:
        return int(self.accel.shape[0])


def _state(table: Any, k: int) -> TableState:
    return TableState(float(table.time[k]), table.angles[k], table.rates[k], TableStatus(int(table.status[k])))


def _calibration(folder: Path) -> dict[str, Any]:
    try:
        return dict(json.loads((folder / "calibration.json").read_text(encoding="utf-8")))
    except (OSError, ValueError, TypeError):
        return {}


def _parameters(cal: dict[str, Any]) -> list[dict[str, str]]:
    params = cal.get("parameters") or {}
    return [{"name": n, "unit": str(p.get("display_unit", ""))} for n, p in params.items()]


def _history_estimates(feed: LiveFeed, cal: dict[str, Any]) -> None:
    """The identification's convergence history from calibration.json as ``estimates`` events."""
    hist = cal.get("history") or {}
    params = cal.get("parameters") or {}
    names = list(params)
    if not hist.get("time") or not names:
        return
    ones = np.array([DISPLAY_UNITS[params[n]["kind"]][1] for n in names])
    for t, step, x, s in zip(hist["time"], hist["step"], hist["estimate"], hist["sigma"], strict=False):
        feed.publish("estimates", {
            "bench_s": round(float(t), 3), "step": step,
            "values": [round(v, 6) for v in (np.asarray(x) / ones).tolist()],
            "u": [round(v, 6) for v in (np.asarray(s) / ones).tolist()],
            "u_meaning": "filter white-noise 1σ (k = 1)",
        })  # fmt: skip

"""The live view's event feed: numbered events, replayable from any id, optionally kept in a JSON-lines file.

A run publishes what the page shows as a sequence of events (``run``, ``step``, ``bins``, ``estimates``,
``health``, ``end``, ``result``), each numbered from 1. A browser that reconnects sends the last id it saw
(server-sent events' ``Last-Event-ID``) and receives every later event, so it continues where it was. The
feed never holds samples: the channels arrive already decimated (:class:`MinMaxDecimator`), so a whole run
is a few thousand small events.

With ``path`` the feed also appends every event to a JSON-lines file in the run folder (``live.jsonl``), one
``{"id": …, "event": …, "data": …}`` object a line; ``tablebench view RUN`` follows that file to show a run
that another process is executing. Numbers in events are display units (``analysis.units``), named in the
event itself.
"""

from __future__ import annotations

import json
import threading
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import IO, Any

import numpy as np
from numpy.typing import NDArray


@dataclass(frozen=True)
class Event:
    """One numbered event of the feed."""

    id: int
    kind: str
    data: dict[str, Any]

    def to_sse(self) -> str:
        """The event in server-sent-events framing (id, event name, one data line of JSON)."""
        return f"id: {self.id}\nevent: {self.kind}\ndata: {json.dumps(self.data, separators=(',', ':'))}\n\n"


class LiveFeed:
    """A thread-safe, append-only list of events with waiting readers.

    Parameters
    ----------
    path : Path, optional
        A JSON-lines file the events are appended to as they are published (created; one line each).
    truncate : bool
        Start ``path`` afresh instead of appending.
    """

    def __init__(self, path: Path | None = None, *, truncate: bool = False) -> None:
        self._events: list[Event] = []
        self._cond = threading.Condition()
        self._closed = False
        self._file: IO[str] | None = None
        if path is not None:
            try:
                self._file = open(path, "w" if truncate else "a", encoding="utf-8")  # noqa: SIM115
            except OSError:  # the live file is a convenience: never stop a run for it
                self._file = None
        self.path = path

    # ---- writing ------------------------------------------------------------------------------------------------
    def publish(self, kind: str, data: dict[str, Any]) -> Event:
        """Append an event (``data`` must be JSON-serialisable and finite) and wake the readers."""
        with self._cond:
            ev = Event(len(self._events) + 1, kind, data)
            self._events.append(ev)
            if self._file is not None:
                try:
                    line = json.dumps({"id": ev.id, "event": kind, "data": data}, allow_nan=False) + "\n"
                except ValueError:  # a non-finite number: the file keeps only strict JSON (the page still gets it)
                    line = ""
                try:
                    if line:
                        self._file.write(line)
                        self._file.flush()
                except OSError:  # the live file is a convenience: never stop a run for it (disk full, …)
                    self._file = None
            self._cond.notify_all()
            return ev

    def close(self) -> None:
        """No more events will come; readers return once they have everything."""
        with self._cond:
            self._closed = True
            if self._file is not None:
                self._file.close()
                self._file = None
            self._cond.notify_all()

    @property
    def closed(self) -> bool:
        """True once :meth:`close` was called."""
        return self._closed

    # ---- reading ------------------------------------------------------------------------------------------------
    def __len__(self) -> int:
        return len(self._events)

    def since(self, last_id: int) -> list[Event]:
        """Every event after ``last_id`` (0: all of them)."""
        with self._cond:
            return self._events[max(int(last_id), 0) :]

    def wait(self, last_id: int, timeout: float) -> list[Event]:
        """Events after ``last_id``, waiting up to ``timeout`` s for one if there is none yet."""
        with self._cond:
            if len(self._events) <= last_id and not self._closed:
                self._cond.wait(timeout)
            return self._events[max(int(last_id), 0) :]

    def events(self) -> Iterator[Event]:
        """A snapshot iterator over all events so far."""
        return iter(self.since(0))

    @classmethod
    def from_lines(cls, lines: list[str]) -> LiveFeed:
        """A closed-or-open feed holding the events of a ``live.jsonl`` file's lines (a partial last line is
        ignored: the writer may be in the middle of it)."""
        feed = cls()
        feed.extend_lines(lines)
        return feed

    def extend_lines(self, lines: list[str]) -> int:
        """Append the events of complete ``live.jsonl`` lines; returns how many were taken."""
        n = 0
        for line in lines:
            if not line.endswith("\n"):
                break
            try:
                obj = json.loads(line)
                kind, data = str(obj["event"]), dict(obj["data"])
            except (ValueError, KeyError, TypeError):
                break
            self.publish(kind, data)
            n += 1
        return n


class MinMaxDecimator:
    """Min/max per bin of bench time: a 1 kHz six-channel stream becomes a fixed number of columns.

    Bins have width ``bin_s``; when the run outlasts ``max_bins`` bins (a run longer than estimated) pairs of
    bins merge and the width doubles, so the series never exceeds ``max_bins`` columns.

    Parameters
    ----------
    n_channels : int
    bin_s : float
        Initial bin width, s of bench time.
    max_bins : int
    """

    def __init__(self, n_channels: int, bin_s: float, max_bins: int = 2400) -> None:
        self.n = int(n_channels)
        self.bin_s = float(bin_s)
        self.max_bins = int(max_bins)
        self.lo: list[NDArray[np.float64]] = []
        self.hi: list[NDArray[np.float64]] = []
        self.extra: list[NDArray[np.float64] | None] = []  # e.g. the table reading at the bin's end
        self._open: int | None = None  # index of the bin still being filled
        self._open_lo = np.full(self.n, np.inf)
        self._open_hi = np.full(self.n, -np.inf)
        self._open_extra: NDArray[np.float64] | None = None

    def add(self, t: NDArray[np.float64], x: NDArray[np.float64], extra: NDArray[np.float64] | None = None) -> bool:
        """Add samples ``x`` (n, channels) at bench times ``t`` (n,), increasing; ``extra``: a vector stored with
        the bins this call touches. Returns True if the bins were merged (the whole series changed)."""
        if len(t) == 0:
            return False
        idx = np.floor(np.asarray(t) / self.bin_s).astype(np.int64)
        cuts = np.flatnonzero(np.diff(idx)) + 1
        starts = np.concatenate(([0], cuts))
        lo = np.minimum.reduceat(x, starts, axis=0)
        hi = np.maximum.reduceat(x, starts, axis=0)
        for k, s in enumerate(starts):
            b = int(idx[s])
            if self._open is not None and b != self._open:
                self._close_open()
            if self._open is None:
                self._open = b
            np.minimum(self._open_lo, lo[k], out=self._open_lo)
            np.maximum(self._open_hi, hi[k], out=self._open_hi)
            self._open_extra = extra
        merged = False
        while self._open is not None and self._open >= self.max_bins:
            self._merge()
            merged = True
        return merged

    def _fill_to(self, n: int) -> None:
        """An empty stretch (no samples) before bin ``n``: repeat the last closed column."""
        while len(self.lo) < n:
            self.lo.append(self.lo[-1] if self.lo else self._open_lo.copy())
            self.hi.append(self.hi[-1] if self.hi else self._open_hi.copy())
            self.extra.append(self.extra[-1] if self.extra else self._open_extra)

    def _close_open(self) -> None:
        assert self._open is not None
        self._fill_to(self._open)
        self.lo.append(self._open_lo.copy())
        self.hi.append(self._open_hi.copy())
        self.extra.append(self._open_extra)
        self._open = None
        self._open_lo.fill(np.inf)
        self._open_hi.fill(-np.inf)

    def _merge(self) -> None:
        """Halve the resolution: pairs of bins merge (bin i becomes i // 2), the bin width doubles."""
        assert self._open is not None
        b = self._open
        self._fill_to(b)
        if b % 2:  # closed bin b - 1 and the open bin b become one bin
            np.minimum(self._open_lo, self.lo.pop(), out=self._open_lo)
            np.maximum(self._open_hi, self.hi.pop(), out=self._open_hi)
            self.extra.pop()
        self.lo = [np.minimum(self.lo[i], self.lo[i + 1]) for i in range(0, len(self.lo), 2)]
        self.hi = [np.maximum(self.hi[i], self.hi[i + 1]) for i in range(0, len(self.hi), 2)]
        self.extra = [self.extra[i + 1] for i in range(0, len(self.extra), 2)]
        self.bin_s *= 2.0
        self._open = b // 2

    def closed_since(self, start: int) -> tuple[int, list[NDArray[np.float64]], list[NDArray[np.float64]], list[Any]]:
        """The closed bins from index ``start`` on: (start, lows, highs, extras)."""
        return start, self.lo[start:], self.hi[start:], self.extra[start:]

    def flush(self) -> None:
        """Close the bin being filled (the end of the run)."""
        if self._open is not None:
            self._close_open()

    def __len__(self) -> int:
        return len(self.lo)

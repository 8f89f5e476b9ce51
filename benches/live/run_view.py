"""The live view of one ``tablebench run``: its feed (``RUN/live.jsonl``), its observer and, with ``--live``, its
server — opened before the table moves, closed on every exit path.

Every run writes its live events to ``RUN/live.jsonl`` (a few MB at most), so ``tablebench view RUN`` can follow
it from another terminal; ``--live [HOST:]PORT`` also serves the page from the run's own process.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from .feed import LiveFeed
from .observer import LiveObserver, publish_result
from .replay import LIVE_FILE
from .server import LiveServer, check_free


class RunView:
    """Feed, observer and optional server of a run.

    Parameters
    ----------
    address : (host, port) or None
        Serve the page there (checked free now, before anything moves); None: only the live file.
    linger_s : float
        After the run's results are published, keep serving this long (wall s) so a page can fetch them.
    say : callable
        Prints one line for the technician.
    """

    def __init__(self, address: tuple[str, int] | None, linger_s: float = 0.0, say: Callable[[str], Any] = print):
        if address is not None:
            check_free(*address)
        self.address = address
        self.linger_s = max(float(linger_s), 0.0)
        self.say = say
        self.feed: LiveFeed | None = None
        self.server: LiveServer | None = None
        self.observer: LiveObserver | None = None
        self.folder: Path | None = None

    def open(self, folder: Path) -> None:
        """Start the feed in ``folder`` (a resumed run starts a new live file) and the server if asked for."""
        self.folder = folder
        self.feed = LiveFeed(folder / LIVE_FILE, truncate=True)
        if self.address is not None:
            self.server = LiveServer(self.feed, *self.address, run_folder=folder).start()
            self.say(f"live view: {self.server.url} (read-only; stop the bench here with Ctrl-C, not from the page)")

    def make_observer(self, steps: Any, sample_rate: float, estimated_s: float, info: dict[str, Any],
                      identifier: Any = None) -> LiveObserver:  # fmt: skip
        """The runner observer publishing to this view's feed."""
        assert self.feed is not None, "open() first"
        self.observer = LiveObserver(
            self.feed, steps, sample_rate=sample_rate, estimated_s=estimated_s, info=info, identifier=identifier
        )
        return self.observer

    def run_ended(self, status: str, reason: str = "") -> None:
        """The recording is closed (any status)."""
        if self.observer is not None:
            self.observer.finish(status, reason)

    def publish_results(self) -> None:
        """calibration.json and the certificate exist (or not): show them."""
        if self.feed is not None and self.folder is not None:
            publish_result(self.feed, self.folder)

    def close(self) -> None:
        """Linger if asked (and a page is served), then stop serving and close the live file."""
        if self.server is not None:
            if self.linger_s > 0:
                self.say(f"live view: serving the results for {self.linger_s:g} s more ({self.server.url})")
                try:
                    time.sleep(self.linger_s)
                except KeyboardInterrupt:
                    pass
            self.server.close()
            self.server = None
        if self.feed is not None:
            self.feed.close()

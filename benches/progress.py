"""Progress display for long bench work: a live bar on a terminal, plain lines otherwise.

Shows the current step, % of the procedure (by estimated bench time), elapsed and remaining time both in
bench time (the unit's sample clock) and wall time, and optional extra text (e.g. live estimates from the
streaming identifier).
"""

from __future__ import annotations

import sys
import time
from collections.abc import Callable
from typing import TextIO

from analysis.units import format_hms as _hms

BAR_REFRESH_S = 0.1
"""The live bar is redrawn at most this often (wall s): the runner updates it every block, hundreds per second."""


class ProgressDisplay:
    """Report progress of a run of known total bench duration.

    Parameters
    ----------
    total_bench_s : float
        Estimated total bench time of the work, s.
    stream : TextIO
        Where to write (default stderr).
    live : bool or None
        Force a live single-line display (True) or plain lines (False); None: live iff ``stream`` is a TTY.
    min_interval_s : float
        Plain-line mode: at most one progress line per this many wall seconds (and one per step).
    """

    def __init__(
        self,
        total_bench_s: float,
        stream: TextIO | None = None,
        live: bool | None = None,
        min_interval_s: float = 5.0,
    ) -> None:
        self.total = max(float(total_bench_s), 1e-9)
        self.stream = stream or sys.stderr
        self.live = self.stream.isatty() if live is None else live
        self.min_interval = min_interval_s
        self.t0 = time.monotonic()
        self._last_print = -1e9
        self._step = ""
        self._extra: str | Callable[[], str] = ""
        self._bar = None
        if self.live:
            from tqdm import tqdm  # lazy: tqdm (--help time)

            self._bar = tqdm(
                total=1000, file=self.stream, bar_format="{l_bar}{bar}| {postfix}", dynamic_ncols=True, leave=True
            )

    def step(self, name: str, description: str = "") -> None:
        """A new step starts."""
        self._step = name
        if not self.live:
            print(f"step {name}{': ' + description if description else ''}", file=self.stream, flush=True)

    def extra(self, text: str | Callable[[], str]) -> None:
        """Set extra text shown with the next update (e.g. live estimates); a callable is asked for it only
        when a line is shown (the runner updates every block; a line is shown far less often)."""
        self._extra = text

    def update(self, bench_elapsed_s: float, *, force: bool = False) -> None:
        """Report that ``bench_elapsed_s`` of the procedure's bench time has passed (shown at most every
        ``min_interval_s`` wall seconds on plain lines and every ``BAR_REFRESH_S`` on the live bar, unless
        ``force``)."""
        now = time.monotonic()
        if not force and now - self._last_print < (BAR_REFRESH_S if self._bar is not None else self.min_interval):
            return
        self._last_print = now
        frac = min(max(bench_elapsed_s / self.total, 0.0), 1.0)
        wall = now - self.t0
        speed = bench_elapsed_s / wall if wall > 0 else float("nan")
        bench_left = max(self.total - bench_elapsed_s, 0.0)
        wall_left = bench_left / speed if speed and speed == speed and speed > 0 else float("nan")
        if bench_elapsed_s <= self.total:
            bench_txt = f"bench {_hms(bench_elapsed_s)}/{_hms(self.total)} ETA {_hms(bench_left)}"
            wall_txt = f"wall {_hms(wall)} ETA {_hms(wall_left)}"
        else:  # past the estimate (settling, a slow controller): never "0:53:58/0:53:31", never a negative ETA
            bench_txt = f"bench {_hms(bench_elapsed_s)}, past the {_hms(self.total)} estimate, ETA unknown"
            wall_txt = f"wall {_hms(wall)}"
        text = f"{self._step} | {bench_txt} | {wall_txt} ({speed:.0f}x real time)"
        extra = self._extra() if callable(self._extra) else self._extra
        if extra:
            text += f" | {extra}"
        if self._bar is not None:
            self._bar.n = int(frac * 1000)
            self._bar.set_description_str(f"{100 * frac:5.1f}%", refresh=False)
            self._bar.set_postfix_str(text, refresh=False)
            self._bar.refresh()
            return
        print(f"{100 * frac:5.1f}% {text}", file=self.stream, flush=True)

    def close(self) -> None:
        """Finish the display."""
        if self._bar is not None:
            self._bar.close()
            self._bar = None


class NullProgress(ProgressDisplay):
    """A progress display that shows nothing (tests, library use)."""

    def __init__(self) -> None:  # noqa: D107 - trivial
        self.live = False

    def step(self, name: str, description: str = "") -> None:  # noqa: D102
        pass

    def extra(self, text: str | Callable[[], str]) -> None:  # noqa: D102
        pass

    def update(self, bench_elapsed_s: float, *, force: bool = False) -> None:  # noqa: D102
        pass

    def close(self) -> None:  # noqa: D102
        pass

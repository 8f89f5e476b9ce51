"""THE interrupt handling and progress of the long analysis commands (noise, periodic, drift, certificate).

Every such command runs its computation through :class:`Work`, the way ``run`` runs a procedure:

- **Interrupts.** The computation runs in a worker thread while the main thread waits in short polls, so
  Ctrl-C (SIGINT), SIGTERM and SIGHUP reach the main thread within a tenth of a second even while the worker
  is inside one long numerical call (an ARMA fit, an FFT of a long record): the command says
  "interrupted" and exits 130 within a second. The worker is told to stop and stops at its next progress
  call; it writes nothing (the ``tablebench`` process then ends at once: :func:`benches.cli.main.main`).
- **Nothing half-written.** Outputs are written by the main thread only after the computation has finished,
  inside :meth:`Work.writing`: a signal arriving while the (short) writes run is held until they are done,
  and every file is written atomically (temporary file + rename), so an interrupted command leaves either
  nothing or every output complete.
- **Progress with an ETA.** The computation reports done/total work units (:meth:`Work.advance`, or
  :meth:`Work.fraction` inside a unit); a plain line on stderr at most every few seconds gives the percent
  done, the current stage, the elapsed wall time and the estimated time left (from the rate so far), as
  the run's display does; a live bar on a terminal.
"""

from __future__ import annotations

import io
import signal
import sys
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any, TextIO, TypeVar

from analysis.units import format_hms

T = TypeVar("T")

POLL_S = 0.05
"""How often the waiting main thread wakes (signals are handled at the latest this much later)."""
QUIET_START_S = 1.0
"""Progress lines start after this much wall time (then with every stage so far): a bad input found at once is
still one error line."""
STOP_SIGNALS = tuple(getattr(signal, n) for n in ("SIGTERM", "SIGHUP") if hasattr(signal, n))
"""Signals that end the work like Ctrl-C (SIGINT raises KeyboardInterrupt by itself)."""


class Cancelled(KeyboardInterrupt):
    """Raised in the worker at its next progress call once the command was interrupted."""


class Work:
    """Run a command's computation interruptibly with progress and an ETA; see the module docstring.

    Parameters
    ----------
    command : str
        The command name (prefix of the progress lines).
    total : float
        Work units of the whole computation (e.g. channels, or channels × stages).
    quiet : bool
        No progress lines.
    stream : TextIO, optional
        Where the progress goes (default stderr).
    interval_s : float
        At most one plain progress line per this many seconds (plus one per new stage).
    """

    def __init__(
        self,
        command: str,
        total: float,
        *,
        quiet: bool = False,
        stream: TextIO | None = None,
        interval_s: float = 2.0,
    ) -> None:
        self.command = command
        self.total = max(float(total), 1e-12)
        self.quiet = quiet
        self.stream = stream or sys.stderr
        self.interval = interval_s
        self._done = 0.0
        self._part = 0.0
        self._stage = ""
        self._pending: list[tuple[str, float]] = []  # stages not shown yet, with the work done when they began
        self._t0 = time.monotonic()
        self._last = -1e9
        self._cancel = threading.Event()
        self._lock = threading.Lock()
        self._held: list[int] = []
        self._holding = False
        self._old: dict[int, Any] = {}

    # ---- context: the signal handlers --------------------------------------------------------------------
    def __enter__(self) -> Work:
        if threading.current_thread() is threading.main_thread():
            for sig in STOP_SIGNALS:
                self._old[sig] = signal.signal(sig, self._on_signal)
            self._old[signal.SIGINT] = signal.signal(signal.SIGINT, self._on_signal)
        return self

    def __exit__(self, *exc: object) -> None:
        for sig, old in self._old.items():
            signal.signal(sig, old)
        self._old.clear()
        self._cancel.set()  # a worker still running (an error elsewhere) stops at its next progress call

    def _on_signal(self, signum: int, _frame: object) -> None:
        if self._holding:
            self._held.append(signum)
            return
        raise KeyboardInterrupt

    # ---- the computation ---------------------------------------------------------------------------------
    def run(self, fn: Callable[..., T], *args: Any, **kwargs: Any) -> T:
        """``fn(*args, **kwargs)`` in a worker thread; the main thread waits, shows progress and handles signals.

        Returns what ``fn`` returns; re-raises what it raises. KeyboardInterrupt (Ctrl-C, SIGTERM, SIGHUP) is
        raised here within :data:`POLL_S` of the signal; the worker is cancelled."""
        box: dict[str, Any] = {}

        def target() -> None:
            try:
                box["value"] = fn(*args, **kwargs)
            except BaseException as exc:  # noqa: BLE001 - handed to the main thread
                box["error"] = exc

        worker = threading.Thread(target=target, name=f"{self.command}-work", daemon=True)
        worker.start()
        try:
            while worker.is_alive():
                worker.join(POLL_S)
                self._show()
        except KeyboardInterrupt:
            self._cancel.set()
            worker.join(0.1)  # a worker at a progress call stops at once; one inside a long call is abandoned
            raise
        if "error" in box:
            raise box["error"]
        self._show(force=True, final=True)
        return box["value"]

    # ---- progress (called by the worker) -----------------------------------------------------------------
    def check(self) -> None:
        """Raise :class:`Cancelled` if the command was interrupted (call it between pieces of work)."""
        if self._cancel.is_set():
            raise Cancelled

    def stage(self, text: str) -> None:
        """The current stage (shown with the next line)."""
        self.check()
        with self._lock:
            self._set_stage(text)

    def _set_stage(self, text: str) -> None:
        if text != self._stage:
            self._stage = text
            self._pending.append((text, min(self._done + self._part, self.total)))

    def advance(self, units: float = 1.0, text: str | None = None) -> None:
        """``units`` more work units are done; ``text``: the next stage."""
        self.check()
        with self._lock:
            self._done = min(self._done + units, self.total)
            self._part = 0.0
            if text is not None:
                self._set_stage(text)

    def fraction(self, f: float, text: str | None = None) -> None:
        """Within the current unit, ``f`` ∈ [0, 1] is done."""
        self.check()
        with self._lock:
            self._part = min(max(float(f), 0.0), 1.0)
            if text is not None:
                self._set_stage(text)

    def _show(self, *, force: bool = False, final: bool = False) -> None:
        """Main thread: one line per stage begun since the last call, else one every ``interval``."""
        if self.quiet:
            return
        now = time.monotonic()
        if not final and now - self._t0 < QUIET_START_S:  # quick work (or a bad input) shows no progress
            return
        with self._lock:
            done = self.total if final else min(self._done + self._part, self.total)
            lines, self._pending = self._pending, []
            stage = self._stage
        if final:
            lines.append(("done", done))
        elif not lines and (force or now - self._last >= self.interval):
            lines.append((stage, done))
        for text, at in lines:
            self._last = now
            elapsed = now - self._t0
            frac = at / self.total
            eta = format_hms(elapsed * (1.0 - frac) / frac) if 0.0 < frac < 1.0 else ("0:00:00" if final else "unknown")
            try:
                print(
                    f"{self.command}: {100 * frac:5.1f}% {text} | elapsed {format_hms(elapsed)}, ETA {eta}",
                    file=self.stream,
                    flush=True,
                )
            except OSError:  # the terminal is gone (SIGHUP): the work goes on
                self.quiet = True
                return

    # ---- writing the outputs (main thread) ---------------------------------------------------------------
    @contextmanager
    def writing(self) -> Iterator[None]:
        """Write the outputs: a signal arriving meanwhile is held until the block ends, then acted on."""
        self._holding = True
        try:
            yield
        finally:
            self._holding = False
        if self._held:
            raise KeyboardInterrupt


__all__ = ["Cancelled", "Work", "figure_png"]


def figure_png(fig: Any, dpi: int) -> bytes:
    """A matplotlib Figure rendered to PNG bytes (in the worker; the main thread writes them atomically)."""
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi)
    return buf.getvalue()

"""``tablebench view``: the live view of a run in a browser — a run that is going on (started in another
terminal or on another machine, followed through its ``live.jsonl``) or a finished one (its recording)."""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from benches.live.replay import LIVE_FILE, JsonlFollower, feed_from_recording
from benches.live.server import DEFAULT_HOST, DEFAULT_PORT, LiveServer, check_free, parse_address
from core.errors import UsageError

EXAMPLES = f"""examples:
  tablebench view runs/20261127-101500-ten-step            # open http://{DEFAULT_HOST}:{DEFAULT_PORT}/
  tablebench view RUN --live 8800                          # another port
  tablebench view RUN --live 0.0.0.0:8765                  # let other machines of the lab network look

The page is read-only: the bench is stopped at the bench (Ctrl-C in the terminal that runs it).
Ctrl-C here stops serving the page only.
"""


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``view`` subcommand."""
    p = sub.add_parser(
        "view",
        help="watch a run (going on or finished) in a browser",
        description="Serve a read-only live view of a run folder: the procedure's steps, the table against its "
        "demand, the unit's channels, the estimates converging, the links' health and, at the end, the result "
        "with links to calibration.json and the certificate. A run that is still going on is followed through "
        "its RUN/live.jsonl; a finished one is shown from its recording.",
        epilog=EXAMPLES,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("run", metavar="RUN", help="a run folder (or its recording.h5)")
    p.add_argument(
        "--live",
        default="",
        metavar="[HOST:]PORT",
        help=f"where to serve the page (default {DEFAULT_HOST}:{DEFAULT_PORT}; another HOST only if you name it)",
    )
    p.add_argument("--seconds", type=float, default=None, help="serve this long, then exit (default: until Ctrl-C)")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Execute ``tablebench view``."""
    if args.seconds is not None and not 0 <= args.seconds < 1e7:
        raise UsageError(f"--seconds {args.seconds}: must be 0 or more (a finite number of seconds)")
    host, port = parse_address(args.live)
    folder = Path(args.run)
    if folder.is_file():
        folder = folder.parent
    live_file = folder / LIVE_FILE
    if not live_file.is_file() and not (folder / "recording.h5").is_file():
        raise UsageError(f"{args.run}: neither live.jsonl nor recording.h5 there; give a run folder printed by 'run'")
    check_free(host, port)
    follower = None
    if live_file.is_file():
        follower = JsonlFollower(live_file).start()
        feed = follower.feed
        what = "following" if not feed.closed else "showing"
    else:
        feed = feed_from_recording(folder)
        what = "showing the recording of"
    server = LiveServer(feed, host, port, run_folder=folder).start()
    print(f"{what} {folder} at {server.url} (read-only; Ctrl-C stops serving)", file=sys.stderr, flush=True)
    try:
        t_end = None if args.seconds is None else time.monotonic() + args.seconds
        while t_end is None or time.monotonic() < t_end:
            time.sleep(0.2)
    except KeyboardInterrupt:
        pass
    finally:
        if follower is not None:
            follower.stop()
        server.close()
    return 0

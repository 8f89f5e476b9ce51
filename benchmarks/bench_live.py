"""Benchmark: a run's speed with the live view against the same run without it (issue 31; target within 5 %).

The motion phase of ``ten-step-fast-spin`` on the simulated bench (in-process, with the streaming identifier as
``tablebench run`` has it), three ways, alternated run by run so the machine's drift hits all alike:

- reference: no live view at all;
- the live file only (what every ``tablebench run`` does: ``RUN/live.jsonl``);
- ``--live``: the live file, the web server, and one connected client reading the event stream as a browser
  would (an HTTP client in a thread).

Section "live" of benchmarks/RESULTS.md.
"""

from __future__ import annotations

import argparse
import io
import statistics
import tempfile
import threading
import time
import urllib.request
from pathlib import Path

from benches.identify import LiveIdentifier
from benches.live.run_view import RunView
from benches.session import execute, prepare
from benchmarks._results import write_section
from benchmarks.simruns import bench_at_rate


def _client(url: str, stop: threading.Event, counter: list[int]) -> None:
    """Read the event stream like a browser, counting events, until told to stop."""
    while not stop.is_set():
        try:
            with urllib.request.urlopen(url + "events", timeout=5) as r:
                for line in r:
                    if line.startswith(b"id: "):
                        counter[0] += 1
                    if stop.is_set():
                        return
        except OSError:
            time.sleep(0.05)


def one_run(bench: Path, procedure: str, mode: str, seed: int) -> tuple[float, float, float, int]:
    """(wall s and process CPU s of the motion phase, bench s, events received by the client) for ``mode``."""
    prep = prepare(bench, procedure)
    folder = Path(tempfile.mkdtemp(prefix="tb-live-")) / "run"
    folder.mkdir(parents=True)
    view = RunView(("127.0.0.1", 0) if mode == "server" else None, say=lambda _s: None)
    stop, counter, client = threading.Event(), [0], None
    if mode != "none":
        view.open(folder)
    if view.server is not None:
        client = threading.Thread(target=_client, args=(view.server.url, stop, counter), daemon=True)
        client.start()

    def observers(progress):  # noqa: ANN001, ANN202
        ident = LiveIdentifier(prep.config)
        out = [ident]
        if mode != "none":
            info = {"bench": prep.config.name, "procedure": prep.compiled.name}
            out.append(
                view.make_observer(prep.compiled.steps, prep.config.unit.sample_rate, prep.estimated_s, info, ident)
            )
        return out

    t0, c0 = time.perf_counter(), time.process_time()
    result = execute(prep, folder, seed=seed, transport=None, live=False, stream=io.StringIO(), observers=observers)
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    view.run_ended(result.status)
    if client is not None:
        time.sleep(0.3)
        stop.set()
    view.close()
    if result.status != "complete":
        raise RuntimeError(f"benchmark run failed: {result.reason}")
    return wall, cpu, result.bench_seconds, counter[0]


def main(argv: list[str] | None = None) -> int:
    """Run the benchmark (``--quick``: 200 Hz, 2 rounds)."""
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--rounds", type=int, default=None)
    args = ap.parse_args(argv)
    rate = 200.0 if args.quick else 1000.0
    rounds = args.rounds or (2 if args.quick else 4)
    bench = bench_at_rate(Path(tempfile.mkdtemp(prefix="tb-live-bench-")), rate)
    modes = ("none", "file", "server")
    walls: dict[str, list[float]] = {m: [] for m in modes}
    cpus: dict[str, list[float]] = {m: [] for m in modes}
    events = 0
    bench_s = 0.0
    for r in range(rounds):
        for m in modes[r % 3 :] + modes[: r % 3]:  # rotate the order each round
            wall, cpu, bench_s, n = one_run(bench, "ten-step-fast-spin", m, seed=3)
            walls[m].append(wall)
            cpus[m].append(cpu)
            events = max(events, n)
            print(f"round {r + 1}: {m:6s} {wall:6.2f} s wall, {cpu:6.2f} s CPU", flush=True)
    med = {m: statistics.median(w) for m, w in walls.items()}
    cpu_med = {m: statistics.median(c) for m, c in cpus.items()}
    names = {
        "none": "no live view (reference)",
        "file": "live file RUN/live.jsonl (every run)",
        "server": "--live: live file + server + one client reading the stream",
    }
    rows = [(names[m], med[m], med[m] / med["none"], cpu_med[m], cpu_med[m] / cpu_med["none"]) for m in modes]
    body = (
        f"Motion phase of `ten-step-fast-spin` at {rate:.0f} Hz, in-process, with the streaming identifier "
        f"({bench_s / 60:.1f} min of bench time); median of {rounds} runs per mode, modes alternated run by run "
        f"in one process. The connected client received {events} events.\n\n"
        "| mode | wall (median) | wall / reference | process CPU (median, all threads) | CPU / reference |\n"
        "|---|---:|---:|---:|---:|\n"
    )
    body += "\n".join(f"| {n} | {w:.2f} s | **{r:.3f}** | {c:.2f} s | {rc:.3f} |" for n, w, r, c, rc in rows)
    body += (
        "\n\nTarget: the run with `--live` within 5 % of the run without it (wall ratio ≤ 1.05). The client is a "
        "thread of the benchmark process, so the CPU column counts its own reading too (a browser is another "
        "process). Per-run walls: "
        + "; ".join(f"{m}: " + ", ".join(f"{w:.2f}" for w in walls[m]) for m in modes)
        + " s."
    )
    write_section("live", "Live view: run speed with and without --live (issue 31)", body)
    print(body)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

"""Benchmark (issue 24): what the time base costs — identification time and recording size, as ratios.

One run of a procedure on the simulated bench with separate clocks (default: ten-step-fast-spin at 1 kHz,
≈ 49 min of bench time, ≈ 3·10⁶ samples) is recorded once. On that same recording, measured in the same process:

* identification (Kalman, the default) with the time base estimated and propagated to the budget
  (``time_base="estimate"``) against the same identification taking the clocks as one (``time_base="none"``):
  the ratio is what the estimation adds (target ≤ 1.10). Each variant is timed ``--repeat`` times, best kept.
* the recording's size: the bytes of the raw time sources (``/timing``) against the bytes of everything else
  (target ≤ 5 % growth).

By default at the bench's 1 kHz and at 100 Hz (the thermal and coverage benches' rate); ``--quick``: 100 Hz only.
"""

from __future__ import annotations

import argparse
import io
import tempfile
import time
from pathlib import Path

from benches.identify import identify_run
from benches.recording import open_recording
from benches.session import execute, prepare
from benchmarks._results import write_section
from procedures.paths import resolve_bench


def _bench(tmp: Path, rate: float | None) -> Path:
    text = resolve_bench("sim").read_text(encoding="utf-8")
    if rate is not None:
        text = text.replace("sample_rate_hz: 1000.0", f"sample_rate_hz: {rate}")
        text = text.replace("anti_alias_hz: 250.0", f"anti_alias_hz: {rate / 4}")
        text = text.replace("latency_ms: 0.7071", f"latency_ms: {1e3 / (2**0.5 * rate):.6g}")
    p = tmp / "bench.yaml"
    p.write_text(text, encoding="utf-8")
    return p


def _best(fn, repeat: int) -> tuple[float, float]:
    """Best wall-clock and best process-CPU time of ``repeat`` calls, s (the CPU time is what the work costs;
    the wall clock is what a shared machine gave)."""
    wall = cpu = float("inf")
    for _ in range(repeat):
        t0, c0 = time.perf_counter(), time.process_time()
        fn()
        wall = min(wall, time.perf_counter() - t0)
        cpu = min(cpu, time.process_time() - c0)
    return wall, cpu


def _alternated(fns: list, repeat: int) -> list[tuple[float, float]]:
    """:func:`_best` of each of ``fns``, their calls alternated (a load change on the machine hits all alike)."""
    out = [(float("inf"), float("inf"))] * len(fns)
    for _ in range(repeat):
        out = [(min(w, b[0]), min(c, b[1])) for (w, c), b in zip(out, [_best(f, 1) for f in fns], strict=True)]
    return out


def _load() -> str:
    try:
        return " ".join(Path("/proc/loadavg").read_text().split()[:3])
    except OSError:  # not Linux
        return "unknown"


def measure(rate: float | None, procedure: str, repeat: int, seed: int = 24) -> dict[str, float]:
    """One run at ``rate`` Hz (None: the bench's 1 kHz), recorded once; the identification with / without the
    time base alternated ``repeat`` times (best of each), and the recording's sizes."""
    with tempfile.TemporaryDirectory() as d:
        tmp = Path(d)
        bench = _bench(tmp, rate)
        prep = prepare(bench, procedure)
        folder = tmp / "run"
        folder.mkdir()
        t0 = time.perf_counter()
        res = execute(prep, folder, seed=seed, transport=None, live=False, stream=io.StringIO())
        t_run = time.perf_counter() - t0
        assert res.status == "complete", res.reason
        with open_recording(folder / "recording.h5") as rec:
            total = rec.storage_bytes()
            timing = rec.storage_bytes("timing")
            n, n_table, fs = rec.n_samples, rec.n_table, float(rec.header.sample_rate_hz)
            truth = rec.truth().parameters
        (w_none, c_none), (w_est, c_est) = _alternated(
            [lambda: identify_run(folder, time_base="none"), lambda: identify_run(folder, time_base="estimate")],
            repeat,
        )
        tb = identify_run(folder, time_base="estimate").time_base.estimate
    return {
        "fs": fs, "n": n, "n_table": n_table, "t_run": t_run, "c_none": c_none, "c_est": c_est, "w_none": w_none,
        "w_est": w_est, "timing": timing, "rest": total - timing,
        "d_off": tb.offset - truth["clock_offset"], "u_off": tb.u_offset, "d_rate": tb.rate - truth["clock_rate"],
        "u_rate": tb.u_rate, "events": len(tb.events), "birge": tb.misfit,
    }  # fmt: skip


def _table(rows: list[dict[str, float]]) -> str:
    head = "| quantity | " + " | ".join(f"{r['fs']:.0f} Hz" for r in rows) + " |\n|---|" + "---:|" * len(rows) + "\n"
    lines = [
        ("samples, table readings", lambda r: f"{r['n']:.0f}, {r['n_table']:.0f}"),
        ("identification with / without the time base, CPU (target ≤ 1.10)",
         lambda r: f"**{r['c_est'] / r['c_none']:.3f}** ({r['c_est']:.2f} / {r['c_none']:.2f} s)"),
        ("the same, wall clock", lambda r: f"{r['w_est'] / r['w_none']:.3f} ({r['w_est']:.2f} / {r['w_none']:.2f} s)"),
        ("the time base's CPU time per run", lambda r: f"{r['c_est'] - r['c_none']:.3f} s"),
        ("recording: bytes of `/timing` / everything else (target ≤ 5 %)",
         lambda r: f"**{100 * r['timing'] / r['rest']:.2f} %** ({r['timing']:.0f} / {r['rest']:.0f} B)"),
        ("`/timing` per table reading", lambda r: f"{r['timing'] / r['n_table']:.1f} B"),
        ("estimated offset − realised", lambda r: f"{r['d_off'] * 1e6:+.2f} µs (u = {r['u_off'] * 1e6:.2f} µs)"),
        ("estimated rate − realised", lambda r: f"{r['d_rate'] * 1e9:+.2f} ppb (u = {r['u_rate'] * 1e9:.2f} ppb)"),
        ("motions used, Birge ratio", lambda r: f"{r['events']:.0f}, {r['birge']:.2f}"),
    ]  # fmt: skip
    return head + "".join(f"| {k} | " + " | ".join(f(r) for r in rows) + " |\n" for k, f in lines)


def main(argv: list[str] | None = None) -> None:
    """Run the benchmark and write its section of RESULTS.md."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="100 Hz only")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--procedure", default="ten-step-fast-spin")
    args = ap.parse_args(argv)
    load = _load()
    rates: list[float | None] = [100.0] if args.quick else [None, 100.0]
    rows = [measure(r, args.procedure, args.repeat) for r in rates]
    body = f"""\
Procedure `{args.procedure}` on `sim`, separate clocks (bench defaults), seed 24, at the unit rates below (100 Hz:
the thermal and coverage benches). Per rate one run, recorded once; on that recording, in the same process, the
two identifications (Kalman, the default) alternated, best of {args.repeat} each. Targets (issue 24): time ratio ≤ 1.10
(the estimate + its budget sensitivities), size ≤ 5 %.
Load average at the start {load}.

{_table(rows)}
The time base's cost is a fixed amount per run (the motions' samples read, one fit per motion, three thinned
batch solves for the budget's sensitivities), so its ratio grows as the identification it is added to shrinks
with the sample rate; the same holds for `/timing` (≈ 13 B per table reading whatever the unit's rate).
"""
    print(body)
    write_section("timebase", "Time base: estimation cost and recording size (issue 24)", body)


if __name__ == "__main__":
    main()

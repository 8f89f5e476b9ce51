"""``tablebench table``: check the connection to a bench's turntable and jog it before a run.

Opens only the table (``benches.factory.open_table``), checks every demand against the bench's limits before
anything is sent, and stops the axes (``stop``: Off on every axis) on Ctrl-C, SIGTERM and SIGHUP. ``move``
returns once the table has settled (or reports the fault that stopped it); ``spin`` returns with the axis
turning and says how to stop it. Degrees and °/s on the command line.
"""

from __future__ import annotations

import argparse
import math
import signal
import sys
import threading
import time
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING, Any, TextIO

from analysis.units import DEG
from benches.bench_config import load_bench
from benches.cli.arguments import add_bench_argument, check_seed
from core.errors import UsageError
from drivers.protocols import AxisLimits, LinkError, TableError, TableState, TableStatus, Turntable
from procedures.paths import default_bench_path, resolve_bench
from procedures.steps import move_time

if TYPE_CHECKING:
    from benches.factory import Bench  # lazy at run time: scipy, pymodbus (--help time)

EXAMPLES = """examples:
  tablebench table status                                  # the simulated bench's table
  tablebench table --bench benches/example-real.yaml idn   # who answers at the bench's VISA resource
  tablebench table --bench benches/example-real.yaml move 0 90 45
  tablebench table --bench benches/example-real.yaml spin inner 10
  tablebench table --bench benches/example-real.yaml stop
  tablebench table --bench benches/example-real.yaml reset-fault   # acknowledge a latched fault (says which)

exit codes: 0 done, 1 the table faulted or the link failed (axes commanded Off where the link allows),
2 bad input (nothing was sent), 130 interrupted (axes commanded Off)
"""

AXES = ("outer", "middle", "inner")
POLL_S = 0.1
"""Wall (real bench) or bench (simulated bench) seconds between readings while waiting."""


class Interrupted(Exception):
    """A signal asked the command to stop."""

    def __init__(self, name: str) -> None:
        super().__init__(name)
        self.name = name


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``table`` subcommand."""
    p = sub.add_parser(
        "table",
        help="check and jog a bench's turntable (status, idn, move, spin, stop, reset-fault)",
        description="Talk to the turntable of a bench alone: read its state, identify the controller, move to "
        "gimbal angles (degrees; returns when settled), spin one axis (°/s; returns with the axis turning) or "
        "stop every axis, or acknowledge a latched fault (reset-fault: says what the fault was; a latched fault "
        "is never reset by a motion command). Every demand is checked against the bench's limits before it is "
        "sent; Ctrl-C, SIGTERM or SIGHUP during a command stops the axes.",
        epilog=EXAMPLES,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    add_bench_argument(p)
    p.add_argument(
        "--transport",
        choices=("in-process", "loopback"),
        default=None,
        help="simulated benches: the controller in memory, or over its real wire on loopback",
    )
    p.add_argument("--seed", type=int, default=None, help="simulator seed (simulated benches)")
    p.add_argument("--timeout", type=float, default=None, metavar="S", help="longest wait for settling, s")
    p.add_argument("action", choices=("status", "idn", "move", "spin", "stop", "reset-fault"), help="what to do")
    p.add_argument("values", nargs="*", help="move: OUTER MIDDLE INNER (°); spin: AXIS RATE (outer|middle|inner, °/s)")
    p.set_defaults(func=run)


def _numbers(values: list[str], n: int, what: str) -> list[float]:
    if len(values) != n:
        raise UsageError(f"{what} needs {n} value(s), got {len(values)}: {' '.join(values) or '(none)'}")
    out = []
    for v in values:
        try:
            x = float(v)
        except ValueError:
            raise UsageError(f"{what}: {v!r} is not a number") from None
        if not math.isfinite(x):
            raise UsageError(f"{what}: {v!r} is not a finite number")
        out.append(x)
    return out


def parse_demand(action: str, values: list[str], limits: Sequence[AxisLimits]) -> tuple[Any, ...]:
    """The demand of ``move``/``spin`` in SI, checked against the bench limits (UsageError: nothing is sent)."""
    if action == "move":
        deg = _numbers(values, 3, "move OUTER MIDDLE INNER")
        for name, x, lim in zip(AXES, deg, limits, strict=True):
            if not lim.allows_demand(x * DEG):
                raise UsageError(
                    f"move: {name} {x:g}° is outside the bench limits {lim.position_range_text()}; nothing was sent"
                )
        return (tuple(x * DEG for x in deg),)
    if action == "spin":
        if len(values) != 2:
            raise UsageError("spin needs AXIS RATE, e.g. 'spin inner 10'")
        name = values[0].lower()
        if name not in AXES:
            raise UsageError(f"spin: axis {values[0]!r} is not one of outer, middle, inner")
        ax = AXES.index(name)
        if limits[ax].absent:
            raise UsageError(f"spin: the table has no {name} axis; nothing was sent")
        (rate,) = _numbers(values[1:], 1, "spin RATE")
        if not limits[ax].allows_rate(rate * DEG):
            raise UsageError(
                f"spin: {rate:g} °/s exceeds the {name} axis limit {limits[ax].rate_max / DEG:g} °/s; nothing was sent"
            )
        return ax, rate * DEG
    if values:
        raise UsageError(f"{action} takes no values, got {' '.join(values)}")
    return ()


def _describe_state(s: TableState) -> str:
    flags = [f.name for f in TableStatus if f and f.name and s.status & f and f != TableStatus.REMOTE]
    ang = ", ".join(f"{n} {math.degrees(a):.4f}°" for n, a in zip(AXES, s.angles, strict=True))
    rat = ", ".join(f"{math.degrees(r):.4f}" for r in s.rates)
    modes = "/".join(m.name.lower() for m in s.modes)
    return f"angles {ang}; rates [{rat}] °/s; modes {modes}; status {' '.join(flags) or 'idle'}"


def _wait(
    table: Turntable, done: Callable[[TableState], bool], timeout: float, pause: Callable[[float], None], what: str
) -> TableState:
    waited = 0.0
    table.heartbeat()
    s = table.read_state()
    while not done(s):
        if s.status & TableStatus.FAULT:
            report = getattr(table, "fault_report", "") or f"fault {s.fault_code.name}"
            raise TableError(f"the table faulted while {what}: {report}")
        if waited >= timeout:
            raise TableError(f"the table did not finish {what} within {timeout:.0f} s")
        pause(POLL_S)
        waited += POLL_S
        table.heartbeat()  # a PLC's watchdog is fed on every reading (nothing is sent where there is none)
        s = table.read_state()
    return s


def execute(
    bench: Bench,
    action: str,
    demand: tuple[Any, ...],
    *,
    out: TextIO,
    timeout: float | None = None,
    pause: Callable[[float], None] | None = None,
    stop_hint: str = "tablebench table stop",
) -> int:
    """Run one action on an open table bench; returns the exit code (faults / lost links raise)."""
    table = bench.turntable
    if pause is None:
        world = bench.world
        pause = (lambda dt: world.produce(max(1, int(round(dt * world.sample_rate))))) if world else time.sleep
    rate_tol = getattr(table, "rate_tol", 0.01 * DEG)
    if action == "idn":
        idn = getattr(table, "idn", None)
        print(idn() if idn else f"{bench.describe()} (this controller has no identification query)", file=out)
        return 0
    table.heartbeat()  # before anything: a strict PLC's watchdog runs from power-up
    if action == "reset-fault":
        return _reset_fault(table, out)
    if action == "status":
        table.read_state()
        pause(getattr(table, "settle_time", 0.0) + POLL_S)  # the settled / at-rest flags need a window of readings
        s = table.read_state()
        print(bench.describe(), file=out)
        print(f"t = {s.time:.3f} s: {_describe_state(s)}", file=out)
        if s.status & TableStatus.FAULT:
            print(f"fault: {getattr(table, 'fault_report', '') or s.fault_code.name}", file=out)
            print("acknowledge it with: tablebench table reset-fault", file=out)
        for e in getattr(table, "stale_errors", []):
            print(f"error left in the controller's queue from before this session: {e}", file=out)
        if hasattr(table, "controller_limits"):
            for name, lim, bench_lim in zip(AXES, table.controller_limits(), table.limits(), strict=True):
                line = (
                    f"controller limits, {name}: rate {lim['rate_position']:g} (position mode) / "
                    f"{lim['rate_rate']:g} (rate mode) °/s, acceleration {lim['accel_position']:g} / "
                    f"{lim['accel_rate']:g} °/s², position [{lim['low']:g}, {lim['high']:g}]°"
                )
                if (
                    bench_lim.rate_max / DEG > lim["rate_rate"] + 1e-9
                    or bench_lim.accel_max / DEG > lim["accel_rate"] + 1e-9
                ):
                    line += (
                        f" — the bench allows more (rate {bench_lim.rate_max / DEG:g} °/s, acceleration "
                        f"{bench_lim.accel_max / DEG:g} °/s²): the controller will limit; check the bench file"
                    )
                print(line, file=out)
        return 0
    if action == "move":
        (target,) = demand
        start = table.read_state()
        t_max = timeout or 3 * move_time(start.angles, target, table.limits()) + 30.0
        table.heartbeat()
        table.move_to(list(target))
        s = _wait(
            table,
            lambda s: bool(s.status & TableStatus.IN_POSITION) and not s.status & TableStatus.MOVING,
            t_max,
            pause,
            "moving",
        )
        print(f"settled: {_describe_state(s)}", file=out)
        return 0
    if action == "spin":
        ax, rate = demand
        lim = table.limits()[ax]
        table.heartbeat()
        table.spin(ax, rate)
        s = _wait(
            table,
            lambda s: bool(s.status & TableStatus.AT_RATE),
            timeout or 3 * abs(rate) / lim.accel_max + 30,
            pause,
            "reaching the rate",
        )
        if hasattr(table, "leave_running"):
            table.leave_running()
        print(
            f"the {AXES[ax]} axis is turning at {rate / DEG:g} °/s ({_describe_state(s)}); stop it with: {stop_hint}",
            file=out,
        )
        if getattr(getattr(table, "map", None), "has_heartbeat", False):
            print(
                "note: this controller has a watchdog; with no heartbeat once this command exits it will bring "
                "the table to rest and latch COMMUNICATION_LOST (a long spin belongs in a procedure)",
                file=out,
            )
        return 0
    # stop
    table.stop()
    s = _wait(
        table,
        lambda s: not s.status & TableStatus.MOVING and all(abs(r) <= rate_tol for r in s.rates),
        timeout or 120.0,
        pause,
        "stopping",
    )
    print(f"at rest: {_describe_state(s)}", file=out)
    return 0


def _reset_fault(table: Turntable, out: TextIO) -> int:
    """``reset-fault``: an operator's acknowledgement of a latched fault; says what the fault was."""
    s = table.read_state()
    if not s.status & TableStatus.FAULT:
        print(f"no fault is latched; nothing to acknowledge ({_describe_state(s)})", file=out)
        return 0
    what = getattr(table, "fault_report", "") or f"fault {s.fault_code.name}"
    said = table.clear_fault()
    what = said if isinstance(said, str) and said else what
    s = table.read_state()
    if s.status & TableStatus.FAULT:
        raise TableError(f"the fault is still latched after the reset ({what}); find its cause at the table")
    print(f"acknowledged and reset: {what}", file=out)
    print(f"now: {_describe_state(s)}", file=out)
    return 0


class _Signals:
    """SIGINT, SIGTERM and SIGHUP raise :class:`Interrupted` in the main thread while a command runs."""

    def __enter__(self) -> _Signals:
        self._old: dict[int, Any] = {}
        if threading.current_thread() is threading.main_thread():
            for name in ("SIGINT", "SIGTERM", "SIGHUP"):
                sig = getattr(signal, name, None)
                if sig is not None:
                    self._old[sig] = signal.signal(sig, self._raise)
        return self

    @staticmethod
    def _raise(signum: int, _frame: Any) -> None:
        raise Interrupted(signal.Signals(signum).name)

    def __exit__(self, *exc: Any) -> None:
        for sig, old in self._old.items():
            signal.signal(sig, old)


def _safe_stop(table: Turntable) -> str:
    try:
        table.stop()
        return "axes commanded Off"
    except Exception as exc:  # noqa: BLE001 - the link may be gone; say so
        return f"could not command Off ({exc.__class__.__name__}: {exc})"


def run(args: argparse.Namespace, out: TextIO | None = None) -> int:
    """Execute ``tablebench table``."""
    from benches import factory  # lazy: scipy, pymodbus (--help time)

    out = out or sys.stdout
    if args.timeout is not None and not (math.isfinite(args.timeout) and 0 < args.timeout <= 86400):
        raise UsageError(f"--timeout {args.timeout!r}: give seconds in (0, 86400]")
    check_seed(args.seed)
    bench_path = resolve_bench(args.bench) if args.bench else default_bench_path()
    config = load_bench(bench_path)
    demand = parse_demand(args.action, list(args.values), config.turntable.limits)
    hint = f"tablebench table --bench {bench_path} stop"
    with _Signals():
        bench = None
        try:
            bench = factory.open_table(config, seed=args.seed, transport=args.transport)
            return execute(bench, args.action, demand, out=out, timeout=args.timeout, stop_hint=hint)
        except Interrupted as exc:
            what = _safe_stop(bench.turntable) if bench is not None else "nothing was moving yet"
            print(f"tablebench table: interrupted ({exc.name}); {what}", file=sys.stderr)
            return 130
        except (TableError, LinkError) as exc:
            what = _safe_stop(bench.turntable) if bench is not None else "nothing was sent"
            kind = "link lost" if isinstance(exc, LinkError) else "table error"
            print(f"tablebench table: {kind}: {exc}; {what}", file=sys.stderr)
            return 1
        finally:
            if bench is not None:
                bench.close()

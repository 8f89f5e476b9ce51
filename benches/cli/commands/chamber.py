"""``tablebench chamber``: check the link to a bench's temperature chamber before a run (docs/protocols/chambers.md).

``status`` reads the set point, the air temperature and the state; ``set T`` clamps nothing — a set point outside
the bench's limits is refused before anything is sent — starts the chamber and writes T, reading it back;
``stop`` takes the exit path every run takes (safe set point, optional warm-up, the dialect's stop). On a
simulated bench the chamber is the simulated world's, served in the bench's dialect on loopback.
"""

from __future__ import annotations

import argparse
import math
import sys
from typing import Any

from analysis.units import celsius_to_kelvin, kelvin_to_celsius
from benches.bench_config import BenchConfig, load_bench
from benches.cli.arguments import add_bench_argument
from core.errors import UsageError
from drivers.chamber.base import ChamberError
from drivers.chamber.safety import leave_safe
from drivers.protocols import LinkError
from procedures.paths import default_bench_path, resolve_bench

EXAMPLES = """examples:
  tablebench chamber --bench benches/sim-thermal.yaml status
  tablebench chamber --bench lab-chamber.yaml set -20      # start the chamber at -20 °C
  tablebench chamber --bench lab-chamber.yaml stop         # safe set point, (warm-up,) stop

exit codes: 0 done, 1 the chamber refused or the link failed, 2 bad input (nothing was sent)
"""


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``chamber`` subcommand."""
    p = sub.add_parser(
        "chamber",
        help="check a bench's temperature chamber (status, set T, stop)",
        description=__doc__,
        epilog=EXAMPLES,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    add_bench_argument(p)
    p.add_argument("action", choices=("status", "set", "stop"), help="what to do")
    p.add_argument("temperature", nargs="?", type=float, help="set point in °C (set)")
    p.set_defaults(func=run)


def _open(config: BenchConfig) -> tuple[Any, list[Any]]:
    """(driver, things to close in order)."""
    assert config.chamber is not None
    if config.chamber.simulated:
        from drivers.sim.chamber_loopback import serve_chamber  # lazy: scipy (--help time)
        from drivers.sim.world import SimulatedWorld  # lazy: scipy (--help time)

        world = SimulatedWorld.from_bench(config)
        server, conn = serve_chamber(world, config.chamber.config)
        return conn.driver, [conn.close, server.close]
    from drivers.chamber.connect import open_chamber  # lazy: pymodbus (--help time)

    conn = open_chamber(config.chamber.config)
    return conn.driver, [conn.close]


def run(args: argparse.Namespace) -> int:
    """status / set / stop; 1 on a chamber error or a lost link (one line)."""
    config = load_bench(resolve_bench(args.bench) if args.bench else default_bench_path())
    if config.chamber is None:
        raise UsageError(f"bench {config.name!r} ({config.path}) has no chamber: section; see benches/BENCH_FORMAT.md")
    settings = config.chamber.config.settings
    if args.action == "set":
        t = args.temperature
        if t is None or not math.isfinite(t):
            raise UsageError("chamber set: give the set point in °C, e.g. 'tablebench chamber set -20'")
        if not settings.allows(celsius_to_kelvin(t)):
            lo, hi = kelvin_to_celsius(settings.setpoint_min), kelvin_to_celsius(settings.setpoint_max)
            raise UsageError(
                f"chamber set {t:g}: outside the bench's set-point limits [{lo:g}, {hi:g}] °C; nothing was sent"
            )
    elif args.temperature is not None:
        raise UsageError(f"chamber {args.action}: takes no temperature")
    closers: list[Any] = []
    try:
        driver, closers = _open(config)
        if args.action == "status":
            print(driver.identify())
            print(driver.read().describe())
        elif args.action == "set":
            driver.start()
            back = driver.set_setpoint(celsius_to_kelvin(args.temperature))
            print(f"set point {kelvin_to_celsius(back):.2f} °C (read back); the chamber is running")
            print(driver.read().describe())
        else:
            problems = leave_safe(driver)
            for line in problems:
                print(line, file=sys.stderr)
            if problems:
                return 1
            print(f"chamber at its safe set point {kelvin_to_celsius(settings.safe_setpoint):g} °C and stopped")
    except (ChamberError, LinkError) as exc:
        print(f"tablebench chamber: {exc}", file=sys.stderr)
        return 1
    finally:
        for fn in closers:
            try:
                fn()
            except Exception:  # noqa: BLE001 - closing must not mask the outcome
                pass
    return 0

"""What every exit path does to the chamber (docs/protocols/chambers.md, "Safety").

None of the three dialects has a host watchdog: a chamber holds its last set point when the host dies. So on
every exit path the bench reaches — normal end, error, Ctrl-C, lost table or unit link — it calls
:func:`leave_safe`: write the bench's safe set point, optionally wait until the air has warmed above a
dew-point margin (a cold stop condenses water on the unit), then stop the chamber with the dialect's stop.
Each step is attempted even if an earlier one failed; nothing here raises.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager

from analysis.units import kelvin_to_celsius
from drivers.chamber.base import Chamber

log = logging.getLogger(__name__)


def leave_safe(
    chamber: Chamber,
    *,
    wait: Callable[[float], None] = time.sleep,
    clock: Callable[[], float] = time.monotonic,
    poll: float = 10.0,
) -> list[str]:
    """Safe set point, optional warm-up, stop. Returns the problems met (empty: all done); never raises.

    Parameters
    ----------
    chamber : Chamber
        The connected driver (its ``settings`` give the safe set point and the warm-up rule).
    wait : callable
        Waits ``s`` seconds between warm-up polls (a simulated bench passes one that advances its clock).
    clock : callable
        The clock of the warm-up time-out, s (same time base as ``wait``).
    poll : float
        Seconds between warm-up polls.
    """
    problems: list[str] = []
    s = chamber.settings
    try:
        chamber.set_setpoint(s.safe_setpoint)
    except Exception as exc:  # noqa: BLE001 - the exit path goes on whatever failed
        problems.append(f"{chamber.name}: safe set point {kelvin_to_celsius(s.safe_setpoint):g} °C not set ({exc})")
    if s.warm_up_below is not None and not problems:
        problems += _warm_up(chamber, wait, clock, poll)
    try:
        chamber.stop()
    except Exception as exc:  # noqa: BLE001
        problems.append(f"{chamber.name}: stop failed ({exc}); stop the chamber at its panel")
    for p in problems:
        log.error(p)
    return problems


def _warm_up(chamber: Chamber, wait: Callable[[float], None], clock: Callable[[], float], poll: float) -> list[str]:
    s = chamber.settings
    assert s.warm_up_below is not None
    t_end = clock() + s.warm_up_timeout
    try:
        while True:
            air = chamber.read().air
            if air >= s.warm_up_below:
                return []
            if clock() >= t_end:
                return [
                    f"{chamber.name}: air still {kelvin_to_celsius(air):.1f} °C after a {s.warm_up_timeout:g} s "
                    "warm-up "
                    f"(threshold {kelvin_to_celsius(s.warm_up_below):g} °C); stopped cold, check for condensation"
                ]
            wait(poll)
    except Exception as exc:  # noqa: BLE001
        return [f"{chamber.name}: warm-up interrupted ({exc})"]


@contextmanager
def chamber_guard(chamber: Chamber, **kw: object) -> Iterator[Chamber]:
    """``with chamber_guard(ch): ...`` — :func:`leave_safe` on every way out of the block (KeyboardInterrupt too)."""
    try:
        yield chamber
    finally:
        leave_safe(chamber, **kw)  # type: ignore[arg-type]

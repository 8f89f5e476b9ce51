"""The chamber seam: what the bench needs from a temperature chamber, whatever its dialect.

Temperatures are kelvin inside tablebench (SI); the drivers convert to °C only when they put a number on the
wire (:func:`analysis.units.celsius_to_kelvin`). A driver receives an already-open transport and never opens a
port (docs/protocols/chambers.md).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Protocol, runtime_checkable

from analysis.units import celsius_to_kelvin, kelvin_to_celsius
from drivers.protocols import LinkError


class ChamberError(RuntimeError):
    """The chamber refused a command or reported an error (NA: reply, Modbus exception, negative simserv code)."""


class ChamberLinkError(LinkError):
    """No reply, a malformed reply or a lost connection to the chamber."""


@dataclass(frozen=True)
class ChamberReading:
    """One reading of the chamber controller.

    Attributes
    ----------
    setpoint : float
        The controller's active set point, K.
    air : float
        The chamber's measured (process) air temperature, K.
    running : bool or None
        True if the chamber is controlling (constant mode / manual run), None if the dialect cannot tell.
    alarm : bool or None
        True if the controller reports an alarm or input error, None if unknown.
    detail : str
        The dialect's own status words, for the event log.
    """

    setpoint: float
    air: float
    running: bool | None = None
    alarm: bool | None = None
    detail: str = ""

    def describe(self) -> str:
        """One line in °C for the console."""
        state = {True: "running", False: "stopped", None: "state unknown"}[self.running]
        alarm = {True: ", ALARM", False: "", None: ""}[self.alarm]
        extra = f" [{self.detail}]" if self.detail else ""
        return (
            f"air {kelvin_to_celsius(self.air):.2f} °C, set point {kelvin_to_celsius(self.setpoint):.2f} °C, "
            f"{state}{alarm}{extra}"
        )


@dataclass(frozen=True)
class ChamberSettings:
    """Settings every chamber dialect shares (bench file ``chamber:`` section; docs/protocols/chambers.md).

    Attributes
    ----------
    setpoint_min, setpoint_max : float
        Set-point limits of the bench, K: every set point is clamped to them before it is sent (thermal-chamber
        spec §4), and the procedure compiler refuses plateaus outside them before anything moves.
    safe_setpoint : float
        Set point written on every exit path before the chamber is stopped, K (default 25 °C, as PyICe's
        "disable" of an F4).
    warm_up_below : float or None
        If the air is colder than this when the bench stops (a dew-point margin), it first holds the safe set
        point until the air reaches it, at most ``warm_up_timeout`` s (None: stop at once).
    warm_up_timeout : float
        Longest wait of that warm-up, s.
    timeout : float
        Reply time-out of every read, s (the public clients use 1–3 s); a time-out takes the exit path.
    readback_tolerance : float
        Largest accepted difference between a written and a read-back set point, K (the wire's resolution).
    """

    setpoint_min: float = celsius_to_kelvin(-40.0)
    setpoint_max: float = celsius_to_kelvin(150.0)
    safe_setpoint: float = celsius_to_kelvin(25.0)
    warm_up_below: float | None = None
    warm_up_timeout: float = 3600.0
    timeout: float = 3.0
    readback_tolerance: float = 0.051

    def __post_init__(self) -> None:
        for name in ("setpoint_min", "setpoint_max", "safe_setpoint", "timeout", "warm_up_timeout"):
            v = getattr(self, name)
            if not math.isfinite(v):
                raise ValueError(f"chamber setting {name} must be finite, got {v!r}")
        if not self.setpoint_min < self.setpoint_max:
            raise ValueError(
                f"chamber set-point limits must satisfy min < max, got {kelvin_to_celsius(self.setpoint_min):g} °C "
                f"and {kelvin_to_celsius(self.setpoint_max):g} °C"
            )
        if not self.setpoint_min <= self.safe_setpoint <= self.setpoint_max:
            raise ValueError(
                f"chamber safe set point {kelvin_to_celsius(self.safe_setpoint):g} °C is outside the set-point "
                f"limits [{kelvin_to_celsius(self.setpoint_min):g}, {kelvin_to_celsius(self.setpoint_max):g}] °C"
            )
        if self.timeout <= 0:
            raise ValueError(f"chamber timeout must be > 0 s, got {self.timeout!r}")

    def clamp(self, temperature: float) -> float:
        """``temperature`` (K) clamped to the set-point limits."""
        return min(max(float(temperature), self.setpoint_min), self.setpoint_max)

    def allows(self, temperature: float) -> bool:
        """Is ``temperature`` (K) a set point the bench accepts? (The one limit rule: compiler and driver.)"""
        t = float(temperature)
        return math.isfinite(t) and self.setpoint_min - 1e-9 <= t <= self.setpoint_max + 1e-9


@runtime_checkable
class Chamber(Protocol):
    """A temperature chamber controller (one control loop: air temperature)."""

    name: str
    settings: ChamberSettings

    def connect(self) -> None:
        """Learn what the driver must know before it writes anything (e.g. the F4's decimals)."""
        ...

    def read(self) -> ChamberReading:
        """Read set point, air temperature and state."""
        ...

    def set_setpoint(self, temperature: float) -> float:
        """Clamp ``temperature`` (K) to the limits, send it, read it back; return the set point now active, K."""
        ...

    def start(self) -> None:
        """Put the chamber in control at its set point (constant mode / manual run)."""
        ...

    def stop(self) -> None:
        """Stop the chamber's control (the dialect's stop; see :func:`drivers.chamber.safety.leave_safe`)."""
        ...

    def identify(self) -> str:
        """The controller's identity text (model, firmware), for the recording."""
        ...

    def close(self) -> None:
        """Release the driver (the transport belongs to whoever opened it)."""
        ...


def to_wire_celsius(temperature: float) -> float:
    """K → °C for the wire."""
    return kelvin_to_celsius(float(temperature))


def from_wire_celsius(value: float) -> float:
    """°C from the wire → K."""
    return celsius_to_kelvin(float(value))

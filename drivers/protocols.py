"""The seams between the orchestrator and hardware: small protocols a real driver and a simulator share.

Frames: gimbal angles are (outer ψ about n-Up, middle θ, inner γ) in rad, with
C_t^n = R_z(ψ) R_x(θ) R_y(γ) (ENU navigation frame n, inner-gimbal frame t). Inertial-unit samples are in
the unit's body frame b, SI (m/s², rad/s, K). Times are bench time in seconds: the unit's sample clock
for the unit, the controller's clock for the table; on a simulated bench both are the one simulated clock.

Drivers receive an already-open transport (a :class:`drivers.transport.MessageTransport` such as a pyvisa
resource, a pymodbus client, a pyserial ``Serial``-like object, or an in-process simulator handle) in their
constructor; they never open ports themselves.
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass, field
from typing import Protocol, runtime_checkable

import numpy as np
from numpy.typing import NDArray

AXIS_NAMES: tuple[str, str, str] = ("outer", "middle", "inner")


class TableStatus(enum.IntFlag):
    """Status bits a turntable controller reports (the bit values are also the wire bits; as plain integers, for
    building a status bit by bit: the ``STATUS_*`` constants below, the one place they are defined)."""

    NONE = 0
    IN_POSITION = 1 << 0  # all position-mode axes within tolerance and settled
    MOVING = 1 << 1  # any axis moving (profile active or not yet settled)
    AT_RATE = 1 << 2  # all rate-mode axes at their commanded rate
    FAULT = 1 << 3  # a fault is latched; see fault_code; clear_fault() to reset
    LIMIT = 1 << 4  # a position / rate limit was hit
    INTERLOCK_OPEN = 1 << 5  # motion inhibited
    WATCHDOG = 1 << 6  # heartbeat lost: the controller brought the table to rest
    REMOTE = 1 << 7  # remote control enabled


# TableStatus's bits as plain integers, defined once here for every driver and simulator that builds a status bit
# by bit on its hot path (an IntFlag's | runs Python code each time) and makes one TableStatus at the end:
# drivers.acutrol.driver (the ACUTROL reading) and drivers.sim.world (the simulated table). Same values as the flags.
STATUS_IN_POSITION: int = int(TableStatus.IN_POSITION)
STATUS_MOVING: int = int(TableStatus.MOVING)
STATUS_AT_RATE: int = int(TableStatus.AT_RATE)
STATUS_FAULT: int = int(TableStatus.FAULT)
STATUS_LIMIT: int = int(TableStatus.LIMIT)
STATUS_INTERLOCK_OPEN: int = int(TableStatus.INTERLOCK_OPEN)
STATUS_WATCHDOG: int = int(TableStatus.WATCHDOG)
STATUS_REMOTE: int = int(TableStatus.REMOTE)


class FaultCode(enum.IntEnum):
    """Latched fault causes (0 = none). Shared by every controller dialect."""

    NONE = 0
    STALL = 1
    POSITION_LIMIT = 2
    RATE_LIMIT = 3
    ACCELERATION_LIMIT = 4
    COMMUNICATION_LOST = 5
    INTERLOCK = 6
    BAD_COMMAND = 7
    AMPLIFIER = 8


class AxisMode(enum.IntEnum):
    """Commanded mode of one gimbal axis."""

    STOP = 0
    POSITION = 1
    RATE = 2


LIMIT_TOLERANCE: float = 1e-9
"""The one tolerance of every limit check, relative to the limit (absolute for a limit smaller than 1):
position limits in rad, rate in rad/s, acceleration in rad/s². Far below any encoder resolution, it only
absorbs the rounding of unit conversions, so what the compiler accepts the runner, the drivers and the
simulated controllers accept too."""


CONTINUOUS_DEMAND_MAX: float = 20 * math.pi
"""Largest |angle| (rad) an operator may demand of a continuous axis: ten turns either way. One turn reaches
every attitude (procedures compile continuous axes into (−π, π]); an unwrapped demand a few turns out is a
deliberate jog, but ``move 0 0 1e9`` (2.8 million turns, ~87 days of way-points) is a typing error."""


def _slack(limit: float) -> float:
    return LIMIT_TOLERANCE * max(1.0, abs(limit))


@dataclass(frozen=True)
class AxisLimits:
    """Limits of one gimbal axis, SI. ``position_min``/``position_max`` are None for a continuous axis.

    The only place that answers "is this position / rate / acceleration allowed?" (with
    :data:`LIMIT_TOLERANCE`): the compiler, the runner, the drivers and the simulated world all ask it.
    """

    rate_max: float  # rad/s
    accel_max: float  # rad/s²
    position_min: float | None = None  # rad
    position_max: float | None = None  # rad

    @property
    def continuous(self) -> bool:
        """True for an axis without position limits."""
        return self.position_min is None and self.position_max is None

    @classmethod
    def absent_axis(cls) -> AxisLimits:
        """The limits of a gimbal the table does not have (a single-axis table's other two): fixed at 0, no rate."""
        return cls(rate_max=0.0, accel_max=0.0, position_min=0.0, position_max=0.0)

    @property
    def absent(self) -> bool:
        """True for a gimbal the table does not have (:meth:`absent_axis`)."""
        return self.rate_max == 0.0 and self.position_min == 0.0 and self.position_max == 0.0

    def position_bounds(self) -> tuple[float, float]:
        """Allowed gimbal angles [low, high], rad, tolerance included (±inf where unlimited)."""
        lo = -math.inf if self.position_min is None else self.position_min - _slack(self.position_min)
        hi = math.inf if self.position_max is None else self.position_max + _slack(self.position_max)
        return lo, hi

    def allows_position(self, angle: float) -> bool:
        """Is gimbal angle ``angle`` (rad) within the position limits? (False for NaN / inf.)"""
        a = float(angle)
        lo, hi = self.position_bounds()
        return math.isfinite(a) and lo <= a <= hi

    def allows_demand(self, angle: float) -> bool:
        """May an operator demand gimbal angle ``angle`` (rad) (``tablebench table move``)? Within the position
        limits and, on a continuous axis, within ±:data:`CONTINUOUS_DEMAND_MAX` (drivers and controllers unwrap
        their own targets freely; an operator's demand never needs more)."""
        a = float(angle)
        hi = CONTINUOUS_DEMAND_MAX + _slack(CONTINUOUS_DEMAND_MAX)
        return self.allows_position(a) and (not self.continuous or -hi <= a <= hi)

    def allows_rate(self, rate: float) -> bool:
        """Is gimbal rate ``rate`` (rad/s, signed) within the rate limit? (False for NaN / inf.)"""
        r = float(rate)
        return math.isfinite(r) and abs(r) <= self.rate_max + _slack(self.rate_max)

    def allows_acceleration(self, accel: float) -> bool:
        """Is angular acceleration ``accel`` (rad/s², signed) within the acceleration limit?"""
        a = float(accel)
        return math.isfinite(a) and abs(a) <= self.accel_max + _slack(self.accel_max)

    def check_position(self, angle: float, axis: int) -> float:
        """``angle`` (rad) of gimbal ``axis`` (0 outer, 1 middle, 2 inner) if allowed; else :class:`TableError`
        naming the axis and its limits (the command is refused before anything is sent)."""
        if not self.allows_position(angle):
            raise TableError(
                f"move_to: {AXIS_NAMES[axis]} axis angle {math.degrees(float(angle)):.4f}° outside its limits "
                f"{self.position_range_text()}; nothing was sent"
            )
        return float(angle)

    def check_rate(self, rate: float, axis: int) -> float:
        """``rate`` (rad/s, signed) of gimbal ``axis`` if within the rate limit; else :class:`TableError`."""
        r = float(rate)
        if not math.isfinite(r):
            raise TableError(f"spin: rate must be finite, got {rate!r}")
        if not self.allows_rate(r):
            raise TableError(
                f"spin: {AXIS_NAMES[axis]} axis rate {math.degrees(r):.4f} °/s exceeds its limit "
                f"{math.degrees(self.rate_max):.4f} °/s; nothing was sent"
            )
        return r

    def position_range_text(self) -> str:
        """The position limits in degrees for messages, e.g. ``"[-90°, 90°]"`` or ``"continuous"``."""
        if self.continuous:
            return f"continuous (a demand within ±{math.degrees(CONTINUOUS_DEMAND_MAX):g}°)"
        if self.absent:
            return "absent (the table has no such axis)"
        lo = "-inf" if self.position_min is None else f"{math.degrees(self.position_min):g}°"
        hi = "+inf" if self.position_max is None else f"{math.degrees(self.position_max):g}°"
        return f"[{lo}, {hi}]"


@dataclass(frozen=True)
class TableState:
    """One reading of the table controller.

    Attributes
    ----------
    time : float
        The reading's time stamp, s: the controller's own clock when it reports one, else the host's clock when
        the answer arrived (docs/methods/time-base.md; the recording keeps every source raw).
    angles : ndarray (3,)
        Reported gimbal angles (outer, middle, inner), rad, encoder-quantised, unwrapped (a continuous
        axis that has spun two turns reports ≈ 4π).
    rates : ndarray (3,)
        Reported gimbal rates, rad/s.
    status : TableStatus
    fault_code : FaultCode
    modes : tuple of AxisMode
    controller_time : float
        The controller's own clock for this reading, s (NaN: the controller reported none).
    host_request, host_answer : float
        The host's clock when the reading was requested and when its answer arrived, s (NaN: not known).
    """

    time: float
    angles: NDArray[np.float64]
    rates: NDArray[np.float64]
    status: TableStatus
    fault_code: FaultCode = FaultCode.NONE
    modes: tuple[AxisMode, AxisMode, AxisMode] = (AxisMode.STOP, AxisMode.STOP, AxisMode.STOP)
    controller_time: float = math.nan
    host_request: float = math.nan
    host_answer: float = math.nan


class TableError(RuntimeError):
    """A turntable command was refused or the controller reported a fault."""


def check_angles(angles: object, limits: tuple[AxisLimits, AxisLimits, AxisLimits]) -> NDArray[np.float64]:
    """Validate an absolute-angle command (rad; outer, middle, inner) against the limits; return it as (3,)
    float (:meth:`AxisLimits.check_position` per axis). :class:`TableError` before anything is sent."""
    a = np.asarray(angles, dtype=float).reshape(-1)
    if a.shape != (3,):
        raise TableError(f"move_to needs 3 gimbal angles (outer, middle, inner) in rad, got shape {a.shape}")
    if not np.all(np.isfinite(a)):
        raise TableError(f"move_to: angles must be finite, got {a.tolist()}")
    for i, (x, lim) in enumerate(zip(a, limits, strict=True)):
        lim.check_position(float(x), i)
    return a


def check_spin(axis: object, rate: float, limits: tuple[AxisLimits, AxisLimits, AxisLimits]) -> tuple[int, float]:
    """Validate a rate command (axis 0/1/2, rad/s) against the limits (:meth:`AxisLimits.check_rate`)."""
    if not isinstance(axis, int | np.integer) or not 0 <= int(axis) <= 2:
        raise TableError(f"spin: axis must be 0 (outer), 1 (middle) or 2 (inner), got {axis!r}")
    ax = int(axis)
    return ax, limits[ax].check_rate(rate, ax)


class LinkError(ConnectionError):
    """The transport to a device failed (connection lost, timeout, unanswered request)."""


@runtime_checkable
class Turntable(Protocol):
    """A three-axis position/rate table."""

    def limits(self) -> tuple[AxisLimits, AxisLimits, AxisLimits]:
        """Per-axis limits (outer, middle, inner)."""
        ...

    def move_to(self, angles: NDArray[np.float64] | list[float]) -> None:
        """Command absolute gimbal angles (outer, middle, inner), rad; returns at once (poll state)."""
        ...

    def spin(self, axis: int, rate: float) -> None:
        """Command a constant rate (rad/s, signed) on gimbal ``axis`` (0 outer, 1 middle, 2 inner)."""
        ...

    def stop(self) -> None:
        """Bring every axis to rest under control (decelerate within limits), not a power cut."""
        ...

    def read_state(self) -> TableState:
        """Read angles, rates, status and fault code."""
        ...

    def heartbeat(self) -> None:
        """Tell the controller's watchdog the client is alive (sends nothing where there is none, e.g. ACL)."""
        ...

    def clear_fault(self) -> None:
        """Reset a latched fault (the table stays at rest)."""
        ...

    def close(self) -> None:
        """Release the driver (does not close a transport it did not open... which is all of them)."""
        ...


@dataclass
class ImuBlock:
    """A block of consecutive inertial-unit samples, decoded to SI, body frame.

    Attributes
    ----------
    counter : ndarray (n,) uint32
        The unit's frame counter (wraps at 2³²).
    time : ndarray (n,) float64
        Sample time stamps, s (the unit's sample clock).
    accel : ndarray (n, 3) float64
        Specific force, m/s², body frame.
    gyro : ndarray (n, 3) float64
        Angular rate, rad/s, body frame.
    temperature : ndarray (n,) float64
        Unit temperature, K.
    status : ndarray (n,) uint16
        Per-sample flags, bit set = invalid: bits 0–2 accel x/y/z, 3–5 gyro x/y/z, 6 temperature, 7 a
        unit-level problem (``drivers.imu_unit.description.FLAG_BITS``); 0 = every channel valid.
    dropped : int
        Frames missing in this block (from counter gaps, including the gap from the previous block).
    rejected : int
        Frames rejected in this block (bad CRC, bad sync/length).
    resets : int
        Counter resets in this block (the counter jumped back: a unit restart), never counted as drops.
    duplicates : int
        Frames repeating the previous counter in this block (dropped, never used twice).
    events : list of str
        Link events the driver wants in the recording's event log.
    host_time : float
        The host's clock when the block's last frame arrived, s (NaN: not known).
    """

    counter: NDArray[np.uint32]
    time: NDArray[np.float64]
    accel: NDArray[np.float64]
    gyro: NDArray[np.float64]
    temperature: NDArray[np.float64]
    status: NDArray[np.uint16]
    dropped: int = 0
    rejected: int = 0
    events: list[str] = field(default_factory=list)
    resets: int = 0
    duplicates: int = 0
    host_time: float = math.nan

    def __len__(self) -> int:
        return int(self.time.shape[0])


@runtime_checkable
class InertialUnit(Protocol):
    """An inertial measurement unit streaming fixed-rate samples."""

    @property
    def sample_rate(self) -> float:
        """Nominal sample rate, Hz."""
        ...

    def read(self, n: int) -> ImuBlock:
        """Return the next ``n`` samples (fewer only if frames were dropped; never blocks forever)."""
        ...

    def close(self) -> None:
        """Release the driver."""
        ...


# ---- auxiliary devices: small capability protocols (after bluesky's protocols.py) --------------------------------


@dataclass(frozen=True)
class Reading:
    """One reading of an auxiliary device: named channels in SI with their units.

    Attributes
    ----------
    values : dict
        Channel name → value, SI (K, Pa, m/s², …).
    units : dict
        Channel name → the SI unit of its value (``"K"``); every channel of ``values`` has one.
    time : float or None
        The device's own time stamp, s, when it gives one (None: the bench stamps the reading with bench time).
    """

    values: dict[str, float]
    units: dict[str, str]
    time: float | None = None


@runtime_checkable
class Readable(Protocol):
    """A device that can be read (bluesky's ``Readable``: ``read()`` with units; here one :class:`Reading`)."""

    def read(self) -> Reading:
        """The current values of every channel, SI, with their units."""
        ...

    def close(self) -> None:
        """Release the driver (the factory closes the link after it)."""
        ...


@runtime_checkable
class Settable(Readable, Protocol):
    """A readable device with a set point (bluesky's ``Movable``): a temperature chamber, a rate source, …

    ``set`` returns at once; the runner waits on ``settled()`` counting bench time, so a wait is never a sleep.
    """

    def set(self, setpoint: float) -> None:
        """Command a new set point (SI: K for a temperature); raises on a refused command."""
        ...

    def settled(self) -> bool:
        """True when the device has reached and holds its set point by its own criterion."""
        ...

    def status(self) -> str:
        """One line for the event log (set point, measured value, state)."""
        ...

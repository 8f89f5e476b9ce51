"""The simulated world: one bench clock driving a three-axis table, the inertial unit on it, and the Earth.

:class:`SimulatedWorld` is the single source of simulated truth. Drivers talk to it in process
(``drivers.sim.inprocess``) or through wire-level servers (Modbus, serial) running in other threads, so
every public method holds one re-entrant lock.

Time: ``time`` is the unit's sample clock, k / f_s for the next sample k; only :meth:`produce` advances it.
With ideal clocks (``SimConfig.clocks.mode == "ideal"``) it is also the table's time: sample k is taken at
t_k = k / f_s, commands take effect at ``time`` and readings are taken and stamped there. With separate clocks
(docs/methods/time-base.md, :class:`~drivers.sim.config.ClockModel`) the physics runs on true time τ: sample k is
taken at τ_k = k / (f_s (1 + ε_u)); the host's clock (true time) advances with the unit's deliveries (batches, transport
latency) — or, while the unit streams free-running (:meth:`anchor_wall_clock`), with the host's real clock — and
with every controller transaction (a reading or a command, each latched after a request latency
and answered after an answer latency); a command takes effect at its latch time (earlier samples keep the
previous motion: each axis keeps the plans it replaced until no sample can need them); a reading is the table
at its latch time, stamped with the controller's clock c₀ + (1 + ε_c) τ. Faults, limit hits and the watchdog
act at sample instants, so the motion (piecewise analytic, ``drivers.sim.motion``) and every random stream are
independent of how :meth:`produce` calls are split; the latencies come from one seeded stream drawn in call
order (same seed and calls → same bytes).

Frames: gimbal angles (outer ψ, middle θ, inner γ), rad, C_t^n = R_z(ψ) R_x(θ) R_y(γ) (``analysis.gimbal``),
C_b^n = C_t^n C_b^t; navigation frame ENU; unit outputs in the body frame b.

Table behaviour (docs/methods/simulation.md): trapezoidal moves at ``slew_fraction``·rate_max and accel_max to the
absolute commanded angle (continuous axes report unwrapped angles), then a damped overshoot; IN_POSITION
once the transient envelope is inside the tolerance for ``in_position_time``. Rate commands ramp at the
acceleration limit; AT_RATE when reached. Physical rate jitter (first-order Gauss–Markov, only on axes
spinning in rate mode) is real motion: it enters the unit's gyro/lever-arm physics and its integral the true
(and so the reported) angle — a random walk of σ·√(2 τ_c T) over a spin of T seconds, which is what the mean
rate of a spin (its angle over time) sees; the next position command's servo absorbs the angle it left (the
move starts from the true angle). Reported angles carry white jitter and encoder quantisation. A realised
table rate error ε_j (``BudgetInputs.rate_error_bound``) makes gimbal axis j turn at (1 + ε_j) × its commanded
rate: the true angle advances at that rate, the encoder reports it, and the reported rate is the measured
rate of that motion (not the command); AT_RATE still refers to the controller's own loop. Optional
gimbal-axis tilts (non-orthogonality) and inner-axis wobble change the true attitude and body rate (their
effect on the angular acceleration, arcsec × ω̇, is neglected); the reported angles do not show them.
Faults: STALL / AMPLIFIER / POSITION_LIMIT halt the axes at once; INTERLOCK / COMMUNICATION_LOST and the
watchdog bring the table to rest under control; any latched fault makes further motion commands raise
:class:`~drivers.protocols.TableError` until :meth:`clear_fault` (stop is always accepted). The watchdog is
fed by :meth:`heartbeat` and by every accepted command; it trips if the table is still moving
``watchdog`` s of bench time after the last feed.
"""

from __future__ import annotations

import math
import threading
from collections.abc import Sequence
from time import monotonic
from typing import Protocol

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy import signal

from analysis import gimbal
from analysis.earth import earth_rate_enu
from drivers.imu_unit.counts import CountScale, RawFrames, concat_frames
from drivers.protocols import (
    STATUS_AT_RATE,
    STATUS_FAULT,
    STATUS_IN_POSITION,
    STATUS_MOVING,
    STATUS_REMOTE,
    AxisLimits,
    AxisMode,
    FaultCode,
    TableError,
    TableState,
    TableStatus,
)
from drivers.sim.chamber import ChamberPhysics
from drivers.sim.config import ACCEL_PARAM_NAMES, SimConfig, gyro_truth
from drivers.sim.imu_model import InertialModel, misalignment_matrix
from drivers.sim.motion import AxisPlan, plan_hold, plan_position, plan_rate, plan_stop


class SimulatedBench(Protocol):
    """A loaded bench file as the world needs it (``benches.bench_config.BenchConfig`` is one)."""

    name: str
    path: object
    simulation: SimConfig | None


CHUNK = 32768
"""Samples evaluated per vectorised pass (bounds memory for long produce() calls)."""

_HALTING = (FaultCode.STALL, FaultCode.AMPLIFIER, FaultCode.POSITION_LIMIT)


def _rot_small(axis: int, angle: float) -> NDArray[np.float64]:
    c, s = math.cos(angle), math.sin(angle)
    if axis == 1:
        return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


class SimulatedWorld:
    """Simulated bench: table + inertial unit + Earth on one clock (thread-safe; see module docstring).

    Parameters
    ----------
    config : SimConfig
        Truth of the bench.
    seed : int
        Seed of every random stream (same seed → identical frames and readings, bit for bit).
    """

    def __init__(self, config: SimConfig, seed: int) -> None:
        self._lock = threading.RLock()
        self.cfg = config
        self._fs = float(config.sample_rate)
        if not self._fs > 0:
            raise ValueError(f"sample_rate must be > 0 Hz, got {config.sample_rate}")
        self._seed = int(seed)
        self._k = 0
        self._mount = np.asarray(config.mounting, dtype=float)
        tb = config.table
        self._limits = tuple(tb.limits)
        self._plans: list[AxisPlan] = [
            plan_hold(0.0, 0.0, AxisMode.POSITION, target=0.0),
            plan_hold(0.0, 0.0, AxisMode.POSITION, target=0.0),
            plan_hold(0.0, 0.0, AxisMode.POSITION, target=0.0),
        ]
        self._switch = [0.0, 0.0, 0.0]  # true time from which each axis's current plan applies
        self._mask: NDArray[np.float64] | None = None  # _spin_mask of the current plans
        self._plans_version = 0
        self._rest_from: tuple[int, float] | None = None  # (version, a time from which all axes are at rest)
        self._rest_rows: dict[int | None, tuple[NDArray[np.float64], ...]] = {}  # of the version _rest_from names
        self._history: list[list[tuple[float, float, AxisPlan]]] = [[], [], []]  # (from, to, plan) replaced
        self._fault = FaultCode.NONE
        self._latched = TableStatus.NONE
        self._feed_k = 0
        self._wd_armed = True
        self._pending = sorted(
            (max(0, math.ceil(f.time * self._fs - 1e-9)), i, f.fault) for i, f in enumerate(config.faults)
        )
        root = np.random.SeedSequence(self._seed)
        # a 4th child leaves the first three streams unchanged (spawn keys are indices)
        unit_ss, table_ss, reading_ss, budget_ss, chamber_ss = root.spawn(5)
        (clock_ss,) = root.spawn(1)  # a 6th child: the first five streams are unchanged
        self._init_clocks(config, clock_ss)
        bi = config.budget_inputs
        self._rng_budget = np.random.default_rng(budget_ss)
        self._att_bound = float(bi.attitude_error_bound) if bi is not None else 0.0
        self._dphi = np.zeros(3)
        self._rotations: tuple[bytes, NDArray[np.float64], NDArray[np.float64]] | None = None
        self._g_anomaly = float(self._rng_budget.normal(0.0, bi.gravity_anomaly_std)) if bi is not None else 0.0
        self._g = config.local_g + self._g_anomaly
        rb = float(bi.rate_error_bound) if bi is not None else 0.0
        self._rate_error = self._rng_budget.uniform(-rb, rb, 3) if rb > 0 else np.zeros(3)
        az = float(getattr(bi, "azimuth_std", 0.0) or 0.0) if bi is not None else 0.0
        self._azimuth_error = float(self._rng_budget.normal(0.0, az)) if az > 0 else 0.0  # drawn after the
        # g anomaly and rate errors, which are the same with or without it; so are the later ones
        tilt = float(getattr(bi, "axis_tilt_bound", 0.0) or 0.0) if bi is not None else 0.0
        self._axis_tilt = self._rng_budget.uniform(-tilt, tilt, 2) if tilt > 0 else np.zeros(2)
        lat_sd = float(getattr(bi, "latitude_std", 0.0) or 0.0) if bi is not None else 0.0
        self._latitude_error = float(self._rng_budget.normal(0.0, lat_sd)) if lat_sd > 0 else 0.0
        self._earth_n = earth_rate_enu(config.latitude + self._latitude_error)
        self._model = InertialModel(config, unit_ss)
        self.chamber: ChamberPhysics | None = None
        if config.chamber is not None:
            self.chamber = ChamberPhysics(config.chamber, np.random.default_rng(chamber_ss))
            self._model.chamber = self.chamber
        self._rng_jitter = np.random.default_rng(table_ss)
        self._reading_entropy = int(reading_ss.generate_state(1)[0])
        self._jit_a = math.exp(-1.0 / (self._fs * tb.rate_jitter_tau)) if tb.rate_jitter_tau > 0 else 0.0
        self._jit_state = np.zeros(3)
        self._jit_angle = np.zeros(3)  # the rate jitter's integral (rad) per axis at the last produced sample
        self._jit_fold: list[tuple[float, float] | None] = [None, None, None]  # (true time, angle) a move absorbs
        self._rest_cache: tuple[tuple[bytes, bytes], NDArray[np.float64], NDArray[np.float64]] | None = None
        self._rest_views: tuple[int, NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]] | None = None
        self._zeros: NDArray[np.float64] | None = None  # read-only (n, 3) zeros of chunks at rest (_zero_rows)
        self._enc_lsb = 2.0 * math.pi / float(2**tb.encoder_bits) if tb.encoder_bits > 0 else 0.0
        e1, e2 = np.asarray(tb.non_orthogonality, dtype=float) + self._axis_tilt
        self._wobble = float(tb.wobble)
        self._nonortho = (e1 != 0.0) or (e2 != 0.0) or self._wobble != 0.0
        self._e1 = _rot_small(1, e1)
        self._e2 = _rot_small(2, e2)

    def _init_clocks(self, config: SimConfig, ss: np.random.SeedSequence) -> None:
        ck = config.clocks
        self._sep = ck.separate
        rng = np.random.default_rng(ss)
        draws = rng.uniform(-1.0, 1.0, 3)  # drawn even for ideal clocks: the latency stream stays the same
        self._eps_u = float(draws[0] * ck.unit_rate_bound) if self._sep else 0.0
        if self._sep and ck.unit_rate is not None:
            self._eps_u = float(ck.unit_rate)
        self._eps_c = float(draws[1] * ck.controller_rate_bound) if self._sep else 0.0
        self._c0 = float(draws[2] * ck.controller_offset_bound) if self._sep else 0.0
        self._fs_true = self._fs * (1.0 + self._eps_u)
        self._rng_clock = rng
        self._host = 0.0  # host clock now (= true time), s
        self._latch_t = 0.0  # true time of the last controller transaction
        self._last_request = self._last_answer = 0.0
        self._wall: tuple[float, float, float] | None = None  # streaming: (monotonic, true time, speed) at start

    def _tau(self, k: int | NDArray[np.int64]) -> float | NDArray[np.float64]:
        """True time of unit sample ``k`` (ideal clocks: k / f_s)."""
        return k / self._fs_true if self._sep else k / self._fs

    def _controller_clock(self, tau: float) -> float:
        return self._c0 + (1.0 + self._eps_c) * tau if self._sep else tau

    def anchor_wall_clock(self, wall: float, factor: float) -> None:
        """The unit started streaming at host monotonic time ``wall``, ``factor`` samples per nominal sample
        period of the host's clock (1 + ε_u: real time; 0: stopped, back to polled). While it streams, true
        time advances with the host's real clock (× factor / (1 + ε_u)), so a controller transaction is latched
        when it is requested — not when the last burst of frames was produced."""
        with self._lock:
            speed = float(factor) / self.unit_clock_factor if self._sep else float(factor)
            self._wall = (float(wall), float(self._tau(self._k)), speed) if factor > 0 else None

    def _jitter(self, mean: float) -> float:
        return float(self._rng_clock.exponential(mean)) if mean > 0 else 0.0

    def _transaction(self) -> float:
        """One controller transaction now (a reading or a command): its latch time (true time, s)."""
        if not self._sep:
            self._latch_t = self._last_request = self._last_answer = self._host = self._k / self._fs
            return self._latch_t
        ck = self.cfg.clocks
        if self._wall is not None:  # real time: the host's clock is the real one
            self._host = max(self._host, self._wall[1] + (monotonic() - self._wall[0]) * self._wall[2])
        self._last_request = self._host
        self._latch_t = self._host + ck.reading_latency + self._jitter(ck.reading_jitter)
        self._host = self._last_answer = self._latch_t + ck.answer_latency + self._jitter(ck.answer_jitter)
        return self._latch_t

    def _delivered(self, k_last: int) -> None:
        """The host has received the frames up to sample ``k_last``: its clock moves to their arrival."""
        if not self._sep:
            self._host = (k_last + 1) / self._fs
            return
        if self._wall is not None:
            return  # real time: the frames travel a real socket and the host's clock is the real one
        ck = self.cfg.clocks
        b = int(ck.batch_frames)
        batch_end = (k_last // b + 1) * b - 1
        arrival = float(self._tau(batch_end)) + ck.link_latency + self._jitter(ck.link_jitter)
        self._host = max(self._host, arrival)

    @property
    def unit_clock_factor(self) -> float:
        """Samples the unit takes per nominal sample period of true time: 1 + ε_u (a real-time stream's speed)."""
        return 1.0 + self._eps_u

    def host_time(self) -> float:
        """The host's clock now, s (the simulated host clock: true time; ideal clocks: the unit's time)."""
        with self._lock:
            return self._host if self._sep else self._k / self._fs

    def clock_truth(self) -> dict[str, float]:
        """The realised clocks: ``offset`` c₀ (s) and ``rate`` ε of t_table = c₀ + (1 + ε) t_unit for readings the
        controller stamps, the unit's and controller's own rate errors, and the host-stamped mapping
        (t_host = offset_host + (1 + rate_host) t_unit, offset_host = the mean answer latency)."""
        ck = self.cfg.clocks
        return {
            "clock_offset": self._c0,
            "clock_rate": (1.0 + self._eps_c) / (1.0 + self._eps_u) - 1.0,
            "unit_clock_rate": self._eps_u,
            "controller_clock_rate": self._eps_c,
            "host_clock_offset": (ck.answer_latency + ck.answer_jitter) if self._sep else 0.0,
            "host_clock_rate": 1.0 / (1.0 + self._eps_u) - 1.0,
        }

    def _set_plan(self, axis: int, plan: AxisPlan, t: float) -> None:
        """Axis ``axis`` follows ``plan`` from true time ``t``; the plan it replaces is kept for earlier times."""
        t = max(float(t), self._switch[axis])
        keep = float(self._tau(self._k)) - 1.0
        hist = [h for h in self._history[axis] if h[1] > keep]
        hist.append((self._switch[axis], t, self._plans[axis]))
        self._history[axis] = hist
        self._switch[axis] = t
        self._plans[axis] = plan
        self._mask = None
        self._plans_version += 1  # the caches of the plans' rest (_at_rest_from, _rest_rows) start again

    def _command_time(self) -> float:
        return self._transaction() if self._sep else self._k / self._fs

    @classmethod
    def from_bench(cls, config: SimulatedBench, seed: int | None = None) -> SimulatedWorld:
        """The world of a simulated bench file (``seed`` None: the bench's default seed)."""
        if config.simulation is None:
            raise ValueError(f"bench {config.name!r} ({config.path}) has no simulation section; it is a real bench")
        return cls(config.simulation, config.simulation.seed if seed is None else seed)

    # ---- properties ----------------------------------------------------------------------------------
    @property
    def sample_rate(self) -> float:
        """Unit sample rate, Hz."""
        return self._fs

    @property
    def scale(self) -> CountScale:
        """The unit's count scale."""
        return self.cfg.scale

    @property
    def time(self) -> float:
        """Bench time of the next sample, s."""
        with self._lock:
            return self._k / self._fs

    @property
    def samples_produced(self) -> int:
        """Sample periods elapsed since start (dropped frames included)."""
        with self._lock:
            return self._k

    # ---- table commands ------------------------------------------------------------------------------
    def table_limits(self) -> tuple[AxisLimits, AxisLimits, AxisLimits]:
        """Per-axis limits (outer, middle, inner), SI."""
        return self._limits  # type: ignore[return-value]

    def _new_attitude_error(self) -> None:
        """A motion command re-positions the table: a new attitude error δφ (navigation frame), if realised."""
        if self._att_bound > 0:
            self._dphi = self._rng_budget.uniform(-self._att_bound, self._att_bound, 3)

    def _check_ready(self) -> None:
        if self._fault != FaultCode.NONE:
            raise TableError(f"table fault {self._fault.name} is latched; clear_fault() before commanding motion")

    def _jitter_angle_at(self, t: float) -> NDArray[np.float64]:
        """The rate jitter's angle (rad, per axis) at true time ``t`` near the last produced sample."""
        out = self._jit_angle.copy()
        for i, fold in enumerate(self._jit_fold):
            if fold is not None and t >= fold[0]:
                out[i] -= fold[1]
        return out

    def _plan_position(self, axis: int, target: float, t: float) -> None:
        """Re-plan gimbal ``axis`` from its state at ``t`` (true time) to a position move to ``target`` (rad).

        The move starts from the true angle: the plan's plus the angle the rate jitter left (then absorbed)."""
        tb = self.cfg.table
        t = max(t, self._switch[axis])
        p0, v0 = self._plans[axis].state(t)
        if self._jit_fold[axis] is None and self._jit_angle[axis] != 0.0:
            self._jit_fold[axis] = (t, float(self._jit_angle[axis]))
            p0 += float(self._jit_angle[axis])
        plan = plan_position(
            t,
            p0,
            v0,
            target,
            self._limits[axis],
            slew_fraction=tb.slew_fraction,
            overshoot=tb.overshoot,
            settle_frequency_hz=tb.settle_frequency_hz,
            settle_time_constant=tb.settle_time_constant,
            tolerance=tb.position_tolerance,
            in_position_time=tb.in_position_time,
        )
        self._set_plan(axis, plan, t)

    def command_position(self, angles: ArrayLike) -> None:
        """Move to absolute gimbal angles (outer, middle, inner), rad.

        Raises
        ------
        TableError
            If a fault is latched or an angle is outside its axis's position limits (nothing moves).
        """
        with self._lock:
            self._apply_due_events(self._k)
            self._check_ready()
            a = np.asarray(angles, dtype=float).reshape(-1)
            if a.shape != (3,) or not np.all(np.isfinite(a)):
                raise TableError(f"position command needs 3 finite angles (rad), got {angles!r}")
            for i, (x, lim) in enumerate(zip(a, self._limits, strict=True)):
                if not lim.allows_position(x):
                    raise TableError(
                        f"axis {i} angle {math.degrees(x):.4f}° is outside its limits {lim.position_range_text()}"
                    )
            t = self._command_time()
            for i in range(3):
                self._plan_position(i, float(a[i]), t)
            self._new_attitude_error()
            self._feed()

    def command_axis_position(self, axis: int, angle: float) -> None:
        """Move one gimbal ``axis`` (0 outer, 1 middle, 2 inner) to the absolute angle ``angle`` (rad); the other
        axes keep their motion (a controller frame that demands one axis, e.g. an ACL way-point). Like every
        motion command it re-positions the table: a new realised attitude error is drawn (if realised).

        Raises
        ------
        TableError
            If a fault is latched, the axis is not 0–2, or the angle is outside its position limits.
        """
        with self._lock:
            self._apply_due_events(self._k)
            self._check_ready()
            if axis not in (0, 1, 2):
                raise TableError(f"axis must be 0 (outer), 1 (middle) or 2 (inner), got {axis!r}")
            x = float(angle)
            lim = self._limits[axis]
            if not math.isfinite(x) or not lim.allows_position(x):
                raise TableError(
                    f"axis {axis} angle {math.degrees(x):.4f}° is outside its limits {lim.position_range_text()}"
                )
            self._plan_position(axis, x, self._command_time())
            self._new_attitude_error()
            self._feed()

    def command_rate(self, axis: int, rate: float) -> None:
        """Spin gimbal ``axis`` (0 outer, 1 middle, 2 inner) at ``rate`` rad/s (signed); others unchanged.

        Raises
        ------
        TableError
            If a fault is latched, the axis is not 0–2, or |rate| exceeds the axis rate limit.
        """
        with self._lock:
            self._apply_due_events(self._k)
            self._check_ready()
            if axis not in (0, 1, 2):
                raise TableError(f"axis must be 0 (outer), 1 (middle) or 2 (inner), got {axis!r}")
            rate = float(rate)
            lim = self._limits[axis]
            if not lim.allows_rate(rate):
                raise TableError(
                    f"rate {math.degrees(rate):.4f} °/s on axis {axis} exceeds its limit "
                    f"{math.degrees(lim.rate_max):.4f} °/s"
                )
            t = max(self._command_time(), self._switch[axis])
            p0, v0 = self._plans[axis].state(t)
            # the table turns at (1 + ε_j) × the command (its realised rate error); the encoder sees that motion
            realised = rate * (1.0 + float(self._rate_error[axis]))
            self._set_plan(axis, plan_rate(t, p0, v0, rate, lim, realised), t)
            self._new_attitude_error()
            self._feed()

    def command_stop(self) -> None:
        """Decelerate every axis to rest at its acceleration limit (always accepted)."""
        with self._lock:
            self._apply_due_events(self._k)
            self._controlled_stop(self._command_time())
            self._feed()

    def clear_fault(self) -> None:
        """Reset a latched fault and its status bits (the table stays as it is: at rest after a fault)."""
        with self._lock:
            self._apply_due_events(self._k)
            self._fault = FaultCode.NONE
            self._latched = TableStatus.NONE

    def heartbeat(self) -> None:
        """Feed the bench-time watchdog (too late if its deadline is already reached at this sample)."""
        with self._lock:
            self._apply_due_events(self._k)
            self._feed()

    def inject_fault(self, fault: FaultCode) -> None:
        """Latch ``fault`` now (STALL/AMPLIFIER/POSITION_LIMIT halt at once; others stop under control)."""
        with self._lock:
            self._apply_fault(FaultCode(fault), self._k)

    # ---- readings ------------------------------------------------------------------------------------
    def table_state(self) -> TableState:
        """Controller reading at the current bench time (angles jittered + encoder-quantised, unwrapped)."""
        with self._lock:
            self._apply_due_events(self._k)
            t = self._transaction()
            p, v = self._state_at(t)
            p = p + self._jitter_angle_at(t)  # the true angle: the plan's plus the rate jitter's integral
            v = v + self._jit_state * self._spin_mask()  # the measured rate of the true (encoder) motion
            tb = self.cfg.table
            if tb.position_jitter > 0:
                rng = np.random.default_rng([self._reading_entropy, self._k])
                p = p + rng.standard_normal(3) * tb.position_jitter
            if self._enc_lsb > 0:
                p = np.rint(p / self._enc_lsb) * self._enc_lsb
            tc = self._controller_clock(t)
            return TableState(
                time=tc,
                angles=p,
                rates=v,
                status=self._status(t),
                fault_code=self._fault,
                modes=tuple(pl.mode for pl in self._plans),  # type: ignore[arg-type]
                controller_time=tc,
                host_request=self._last_request,
                host_answer=self._last_answer,
            )

    def table_acceleration(self) -> NDArray[np.float64]:
        """Gimbal angular accelerations (outer, middle, inner) at the current bench time, rad/s² (commanded
        profile, no jitter): what a controller's acceleration feedback reads."""
        with self._lock:
            self._apply_due_events(self._k)
            t = self._latch_t if self._sep else self._k / self._fs
            _, _, acc = self._evaluate(np.array([t]))
            return acc[0].copy()

    def _status(self, t: float) -> TableStatus:
        # the bits as integers (drivers.protocols.STATUS_*), one TableStatus at the end (an IntFlag's | runs Python
        # code every time)
        st = STATUS_REMOTE | int(self._latched)
        if any(t < pl.t_still for pl in self._plans):
            st |= STATUS_MOVING
        pos = [pl for pl in self._plans if pl.mode == AxisMode.POSITION]
        if pos and all(t >= pl.t_done for pl in pos):
            st |= STATUS_IN_POSITION
        rate = [pl for pl in self._plans if pl.mode == AxisMode.RATE]
        if rate and all(t >= pl.t_done for pl in rate):
            st |= STATUS_AT_RATE
        if self._fault != FaultCode.NONE:
            st |= STATUS_FAULT
        return TableStatus(st)

    # ---- temperature chamber (docs/methods/thermal.md) --------------------------------------------------
    def _need_chamber(self) -> ChamberPhysics:
        if self.chamber is None:
            raise ValueError("this simulated bench has no chamber (simulation: chamber: section)")
        return self.chamber

    def chamber_setpoint(self, temperature: float) -> bool:
        """Command the chamber's set point (K) now; False (nothing changed) outside the controller's range."""
        with self._lock:
            ch = self._need_chamber()
            if not ch.allows(float(temperature)):
                return False
            ch.command_setpoint(self._k / self._fs, float(temperature))
            return True

    def chamber_run(self, on: bool) -> None:
        """Start or stop the chamber now."""
        with self._lock:
            self._need_chamber().command_run(self._k / self._fs, on)

    def chamber_reading(self) -> tuple[float, float, bool, bool]:
        """(set point K, air reading K, running, alarm) now, as the controller reports them."""
        with self._lock:
            ch = self._need_chamber()
            return ch.setpoint, ch.air_reading(self._k / self._fs), ch.running, ch.alarm

    def chamber_truth(self) -> tuple[float, float, float]:
        """(true air K, true unit temperature K, its rate K/s) now (scoring and tests only)."""
        with self._lock:
            ch = self._need_chamber()
            t = np.array([self._k / self._fs])
            return ch.air_temperature(float(t[0])), float(ch.unit_temperature(t)[0]), float(ch.unit_rate(t)[0])

    # ---- sample generation ---------------------------------------------------------------------------
    def produce(self, n: int) -> RawFrames:
        """Advance the clock by ``n`` sample periods; return the frames emitted (fewer if frames drop)."""
        n = int(n)
        if n < 0:
            raise ValueError(f"n must be >= 0, got {n}")
        with self._lock:
            parts: list[RawFrames] = []
            k_end = self._k + n
            while self._k < k_end:
                k = self._k
                self._apply_due_events(k)
                k1 = min(k_end, self._next_event(k), k + CHUNK)
                idx = np.arange(k, k1, dtype=np.int64)
                t = self._tau(idx)
                static = self._at_rest_from(float(t[0]))  # (a static chunk: no history piece applies either)
                if static:  # every row equals the first (see _at_rest_from), which AxisPlan.state gives bit for bit
                    ang, rat, acc = self._static_rows(float(t[0]), t.shape[0])
                else:
                    ang, rat, acc = self._evaluate(t)
                hit = self._limit_hit(ang)
                if hit is not None:
                    j, axis = hit
                    if j == 0:
                        self._limit_fault(axis, k)
                        continue
                    k1 = k + j
                    t, ang, rat, acc = t[:j], ang[:j], rat[:j], acc[:j]
                parts.append(self._frames(k, t, ang, rat, acc, static))
                self._k = k1
                if hit is not None:
                    self._limit_fault(hit[1], k1)
            if n > 0:
                self._delivered(k_end - 1)
            if self.chamber is not None:
                self.chamber.forget_before(self._k / self._fs)
            return concat_frames(parts)

    def _evaluate(self, t: NDArray[np.float64]) -> tuple[NDArray[np.float64], ...]:
        """Angles, rates, accelerations (n, 3) at sorted true times ``t``: each time by the plan that applied then."""
        n = t.shape[0]
        ang, rat, acc = np.empty((n, 3)), np.empty((n, 3)), np.empty((n, 3))
        for i, plan in enumerate(self._plans):
            if n == 0 or t[0] >= self._switch[i] or not self._history[i]:
                ang[:, i], rat[:, i], acc[:, i] = plan.evaluate(t)
                continue
            pieces = [*self._history[i], (self._switch[i], math.inf, plan)]
            for j, (t_from, t_to, pl) in enumerate(pieces):
                m = (t < t_to) if j == 0 else (t >= t_from) & (t < t_to)
                if np.any(m):
                    ang[m, i], rat[m, i], acc[m, i] = pl.evaluate(t[m])
        return ang, rat, acc

    def _state_at(self, t: float) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Angles (3,) rad and rates (3,) rad/s at one true time ``t``: :meth:`_evaluate` for one time, on
        scalars where each axis's current plan applies (the same bits; a reading per block asks for one)."""
        if any(t < sw and hist for sw, hist in zip(self._switch, self._history, strict=True)):
            pa, va, _ = self._evaluate(np.array([t]))
            return pa[0], va[0]
        if self._at_rest_from(t):  # the same state at every later time (see _at_rest_from): formed once
            rows = self._rest_rows.get(None)
            if rows is None:
                (p0, v0), (p1, v1), (p2, v2) = (plan.state(t) for plan in self._plans)
                rows = self._rest_rows[None] = (np.array([p0, p1, p2]), np.array([v0, v1, v2]))
                for a in rows:
                    a.flags.writeable = False
            return rows[0], rows[1]
        (p0, v0), (p1, v1), (p2, v2) = (plan.state(t) for plan in self._plans)
        return np.array([p0, p1, p2]), np.array([v0, v1, v2])

    def _static_rows(self, t0: float, n: int) -> tuple[NDArray[np.float64], ...]:
        """Angles, rates and accelerations (n, 3) of a static chunk starting at true time ``t0``: the first row
        (:meth:`AxisPlan.state`, the same bits as :meth:`_evaluate`) broadcast; rates and accelerations, +0 at
        rest, are one shared read-only zero array. At rest they are the same at every later time (see
        :meth:`_at_rest_from`): formed once per length until a plan changes."""
        rows = self._rest_rows.get(n)
        if rows is not None:
            return rows
        (p0, v0), (p1, v1), (p2, v2) = (plan.state(t0) for plan in self._plans)
        ang = np.broadcast_to(np.array([p0, p1, p2]), (n, 3))
        rows = ([v0, v1, v2], [float(plan.a[-1]) for plan in self._plans])
        rat, acc = (
            self._zero_rows(n)
            if all(x == 0.0 and math.copysign(1.0, x) > 0 for x in r)
            else np.broadcast_to(np.array(r), (n, 3))
            for r in rows
        )
        self._rest_rows[n] = (ang, rat, acc)
        return ang, rat, acc

    def _zero_rows(self, n: int) -> NDArray[np.float64]:
        """One shared read-only (n, 3) array of +0 (the rates and accelerations of chunks at rest)."""
        if self._zeros is None or self._zeros.shape[0] != n:
            self._zeros = np.zeros((n, 3))
            self._zeros.flags.writeable = False
        return self._zeros

    def _at_rest_from(self, t0: float) -> bool:
        """Every axis is at rest from true time ``t0`` on: in its current plan's last segment with zero rate and
        acceleration and past its settling transient. :meth:`_evaluate` then gives every later time the same
        angle p + 0·dt + 0·dt² = p (dt ≥ 0), rate 0 and acceleration 0, so a hold's block is evaluated once.
        Every condition is t0 < (a time) or does not depend on t0: once true, true later (kept per plans)."""
        rf = self._rest_from
        if rf is not None and rf[0] == self._plans_version and t0 >= rf[1]:
            return True
        for plan, switch, hist in zip(self._plans, self._switch, self._history, strict=True):
            if (hist and t0 < switch) or t0 < plan.t[-1] or plan.v[-1] != 0.0 or plan.a[-1] != 0.0:
                return False
            if plan.settle_t0 is not None and plan.settle_amp != 0.0 and t0 < plan.settle_end:
                return False
        if rf is None or rf[0] != self._plans_version:
            self._rest_rows = {}
        self._rest_from = (self._plans_version, t0)
        return True

    def _spin_mask(self) -> NDArray[np.float64]:
        """1 for each axis spinning under a rate command, else 0 (read-only; kept until a plan changes)."""
        if self._mask is None:
            mask = np.array([1.0 if (pl.mode == AxisMode.RATE and pl.rate_cmd != 0.0) else 0.0 for pl in self._plans])
            mask.flags.writeable = False
            self._mask = mask
        return self._mask

    def _frames(
        self,
        k: int,
        t: NDArray[np.float64],
        ang: NDArray[np.float64],
        rat: NDArray[np.float64],
        acc: NDArray[np.float64],
        static: bool = False,
    ) -> RawFrames:
        """The unit's frames for the samples at true times ``t`` with the table's motion ``ang, rat, acc`` (n, 3);
        ``static``: :meth:`_at_rest_from` holds for the chunk (its rows are equal, rates and accelerations 0)."""
        n = t.shape[0]
        tb = self.cfg.table
        w = self._rng_jitter.standard_normal((n, 3))
        mask = self._spin_mask()
        jittered = tb.rate_jitter > 0 and bool(mask.any())
        if jittered:
            a = self._jit_a
            x, _ = signal.lfilter(
                [1.0], [1.0, -a], w * (tb.rate_jitter * math.sqrt(1 - a * a)), axis=0, zi=a * self._jit_state[None, :]
            )
            self._jit_state = x[-1].copy()
            rat = rat + x * mask
            # the jitter is real motion: its integral (rectangle rule at the sample period) turns the true angle
            phi = self._jit_angle + np.cumsum(x * mask, axis=0) * float(self._tau(1))
        else:
            self._jit_state = np.zeros(3)
            phi = None  # every row is the angle the jitter has left (unless a move absorbs it in this chunk)
        turned = False
        if not n:
            pass
        elif phi is None and all(fold is None or t[-1] < fold[0] for fold in self._jit_fold):
            if self._jit_angle.any():
                ang = ang + self._jit_angle
                turned = True
        else:
            if phi is None:
                phi = np.broadcast_to(self._jit_angle, (n, 3)).copy()
            for i, fold in enumerate(self._jit_fold):
                if fold is not None and t[-1] >= fold[0]:
                    phi[t >= fold[0], i] -= fold[1]
                    self._jit_fold[i] = None
            self._jit_angle = phi[-1].copy()
            if np.any(phi):
                ang = ang + phi
                turned = True
        if (static and not jittered and not turned) or (
            not np.any(rat) and not np.any(acc) and not np.any(ang[1:] != ang[0])
        ):
            # at rest during the whole chunk: one attitude, broadcast (identical values, less work); the
            # attitude's gravity and Earth rate are kept while the table stays there (a hold is many blocks)
            key = (ang[0].tobytes(), self._dphi.tobytes())
            if self._rest_cache is None or self._rest_cache[0] != key:
                c1, _, _ = self._kinematics(ang[:1], rat[:1], acc[:1])
                self._rest_cache = (key, self._g * c1[0, 2, :], self._earth_n @ c1[0])
                self._rest_views = None
            if self._rest_views is None or self._rest_views[0] != n:
                rows = self._rest_cache
                self._rest_views = (
                    n,
                    np.broadcast_to(rows[1], (n, 3)),
                    np.broadcast_to(rows[2], (n, 3)),
                    self._zero_rows(n),
                )
            _, f0, earth_b, omega = self._rest_views
            return self._model.frames(k, f0, omega, omega, earth_b, rest_key=key)
        c_bn, omega, alpha = self._kinematics(ang, rat, acc)
        f0 = self._g * c_bn[:, 2, :]
        earth_b = self._earth_n @ c_bn
        return self._model.frames(k, f0, omega, alpha, earth_b)

    def _kinematics(
        self, ang: NDArray[np.float64], rat: NDArray[np.float64], acc: NDArray[np.float64]
    ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
        """C_b^n (n,3,3), body rate ω^b (n,3) rad/s and angular acceleration ω̇^b (n,3) rad/s² (w.r.t. Earth)."""
        th, ga = ang[:, 1], ang[:, 2]
        psid, thd, gad = rat[:, 0], rat[:, 1], rat[:, 2]
        psidd, thdd, gadd = acc[:, 0], acc[:, 1], acc[:, 2]
        sth, cth = np.sin(th), np.cos(th)
        sg, cg = np.sin(ga), np.cos(ga)
        # perfect gimbals: ω^t = R_y(γ)ᵀ [θ̇, ψ̇ sθ, ψ̇ cθ] + γ̇ e_y, and its time derivative
        v1x, v1z = thd, psid * cth
        d1x, d1y, d1z = thdd, psidd * sth + psid * thd * cth, psidd * cth - psid * thd * sth
        alpha_t = np.stack(
            [
                cg * d1x - sg * d1z - gad * (sg * v1x + cg * v1z),
                d1y + gadd,
                sg * d1x + cg * d1z + gad * (cg * v1x - sg * v1z),
            ],
            -1,
        )
        if not self._nonortho:
            c_tn = gimbal.table_to_nav(ang)
            omega_t = gimbal.table_rate(ang, rat)
        else:
            # C_t^n = R_z(ψ) E1 R_x(θ) E2 W_x W_z R_y(γ): E1, E2 the axis tilts, W_x = R_x(w cos γ),
            # W_z = R_z(w sin γ) the inner-axis wobble (a tilt whose direction turns once per inner revolution).
            # Each factor's rate q̇_k a_k contributes (product of the later factors)ᵀ q̇_k a_k to ω^t.
            rz = gimbal._rz(ang[:, 0])
            rx = gimbal._rx(th)
            ry = gimbal._ry(ga)
            wz_ry = gimbal._rz(self._wobble * sg) @ ry
            inner = self._e2 @ gimbal._rx(self._wobble * cg) @ wz_ry  # C_t^m
            mid = self._e1 @ rx @ inner  # C_t^o
            c_tn = rz @ mid
            ez = np.array([0.0, 0.0, 1.0])
            ex = np.array([1.0, 0.0, 0.0])
            omega_t = (
                psid[:, None] * np.einsum("nij,i->nj", mid, ez)
                + thd[:, None] * np.einsum("nij,i->nj", inner, ex)
                - (self._wobble * sg * gad)[:, None] * np.einsum("nij,i->nj", wz_ry, ex)
                + (self._wobble * cg * gad)[:, None] * np.einsum("nij,i->nj", ry, ez)
                + np.stack([np.zeros_like(gad), gad, np.zeros_like(gad)], -1)
            )
            # ω̇ from perfect-gimbal kinematics (the arcsec-level tilt/wobble effect on ω̇ is neglected)
        c_bn = c_tn @ self._mount
        if self._azimuth_error != 0.0:
            # installation: the outer gimbal's zero is δψ off East (a rotation about the local vertical)
            c_bn = self._fixed_rotations()[0] @ c_bn
        if np.any(self._dphi):
            # realised table attitude error: C_b^n,true = R(δφ) C_b^n,reported (navigation-frame rotation)
            c_bn = self._fixed_rotations()[1] @ c_bn
        omega_b = omega_t @ self._mount
        alpha_b = alpha_t @ self._mount
        return c_bn, omega_b, alpha_b

    def _fixed_rotations(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """R_z(δψ) of the azimuth error and R(δφ) of the realised attitude error (3, 3), formed once per δφ (a
        moving block asks for them every time; the same matrices, so the same products)."""
        key = self._dphi.tobytes()
        if self._rotations is None or self._rotations[0] != key:
            rz = gimbal._rz(np.full(1, self._azimuth_error))[0]
            from scipy.spatial.transform import Rotation

            self._rotations = (key, rz, Rotation.from_rotvec(self._dphi).as_matrix())
        return self._rotations[1], self._rotations[2]

    # ---- events --------------------------------------------------------------------------------------
    def _feed(self) -> None:
        self._feed_k = self._k
        self._wd_armed = True

    def _watchdog_index(self) -> int | None:
        wd = self.cfg.table.watchdog
        if not wd or not self._wd_armed:
            return None
        return self._feed_k + max(1, math.ceil(wd * self._fs - 1e-9))

    def _next_event(self, k: int) -> int:
        cand = [kk for kk, _, _ in self._pending if kk > k]
        w = self._watchdog_index()
        if w is not None and w > k:
            cand.append(w)
        return min(cand) if cand else k + CHUNK

    def _apply_due_events(self, k: int) -> None:
        while self._pending and self._pending[0][0] <= k:
            kk, _, fault = self._pending.pop(0)
            self._apply_fault(fault, kk)
        w = self._watchdog_index()
        if w is not None and w <= k:
            self._wd_armed = False
            t = float(self._tau(w))
            if any(t < pl.t_still for pl in self._plans):
                self._controlled_stop(t)
                self._latch(FaultCode.COMMUNICATION_LOST, TableStatus.WATCHDOG)

    def _latch(self, fault: FaultCode, bits: TableStatus) -> None:
        if self._fault == FaultCode.NONE:
            self._fault = fault
        self._latched |= bits

    def _controlled_stop(self, t: float) -> None:
        for i in range(3):
            ti = max(t, self._switch[i])
            p0, v0 = self._plans[i].state(ti)
            self._set_plan(i, plan_stop(ti, p0, v0, self._limits[i]), ti)

    def _halt(self, t: float, axes: Sequence[int] = (0, 1, 2)) -> None:
        for i in axes:
            ti = max(t, self._switch[i])
            p0, _ = self._plans[i].state(ti)
            self._set_plan(i, plan_hold(ti, p0), ti)

    def _apply_fault(self, fault: FaultCode, k: int) -> None:
        if fault == FaultCode.NONE:
            return
        t = float(self._tau(k))
        if fault in _HALTING:
            self._halt(t)
        else:
            self._controlled_stop(t)
        bits = {
            FaultCode.POSITION_LIMIT: TableStatus.LIMIT,
            FaultCode.RATE_LIMIT: TableStatus.LIMIT,
            FaultCode.ACCELERATION_LIMIT: TableStatus.LIMIT,
            FaultCode.INTERLOCK: TableStatus.INTERLOCK_OPEN,
            FaultCode.COMMUNICATION_LOST: TableStatus.WATCHDOG,
        }.get(fault, TableStatus.NONE)
        self._latch(fault, bits)

    def _limit_hit(self, ang: NDArray[np.float64]) -> tuple[int, int] | None:
        first: tuple[int, int] | None = None
        for i, lim in enumerate(self._limits):
            if lim.continuous:
                continue
            if self._plans[i].mode == AxisMode.POSITION:
                continue  # commanded targets are inside the limits; a settling overshoot is not a limit hit
            lo, hi = lim.position_bounds()
            bad = np.flatnonzero((ang[:, i] < lo) | (ang[:, i] > hi))
            if bad.size and (first is None or bad[0] < first[0]):
                first = (int(bad[0]), i)
        return first

    def _limit_fault(self, axis: int, k: int) -> None:
        """Axis ``axis`` crossed a position limit at sample ``k``: hold it at the limit, stop the others."""
        t = max(float(self._tau(k)), self._switch[axis])
        lim = self._limits[axis]
        p, _ = self._plans[axis].state(t)
        lo = -math.inf if lim.position_min is None else lim.position_min
        hi = math.inf if lim.position_max is None else lim.position_max
        self._set_plan(axis, plan_hold(t, min(max(p, lo), hi)), t)
        others = [i for i in range(3) if i != axis]
        for i in others:
            ti = max(t, self._switch[i])
            p0, v0 = self._plans[i].state(ti)
            self._set_plan(i, plan_stop(ti, p0, v0, self._limits[i]), ti)
        self._latch(FaultCode.POSITION_LIMIT, TableStatus.LIMIT)

    # ---- truth ---------------------------------------------------------------------------------------
    def truth(self) -> dict[str, float]:
        """The 18 accelerometer-model parameters and the gyro model's, by name, SI, as the models identify them.

        Gyro names (``docs/methods/gyro-calibration.md``): ``gyro_b_*``, ``gyro_S_*``, ``gyro_tau_*`` and all
        nine ``gyro_G_*`` (the default model identifies the diagonal three); the simulated gyro has no
        quadratic or asymmetry term unless configured, when ``gyro_S2_*``/``gyro_A_*`` are added.

        The size effect is the lever-arm term as the accelerometer senses it: accelerometer i (sensing row
        m_i = e_i + S_i e_i + τ_ij e_j + τ_ik e_k of I+S+T) at ρ_i, during a spin at ω about body axis j ≠ i,
        reads m_i·(ω×(ω×ρ_i)) = −ω² [(1+S_i) ρ_ii + τ_ik ρ_ik] (k the third axis), while the model writes
        r_i c_i = r_i ω². The τ term depends on which axis spins; the ten-step sequences spin equally about
        the two axes that excite r_i, so the identifiable truth is

            r_i = −(1+S_i) ρ_ii − ½ Σ_{k≠i} τ_ik ρ_ik.
        """
        a = self.cfg.accel
        rho = np.asarray(a.lever_arms, dtype=float)
        m = np.eye(3) + np.diag(a.scale) + misalignment_matrix(a.misalignment)
        r = np.empty(3)
        for i in range(3):
            others = [k for k in range(3) if k != i]
            r[i] = -m[i, i] * rho[i, i] - 0.5 * sum(m[i, k] * rho[i, k] for k in others)
        vals = [*a.bias, *a.scale, *a.misalignment, *a.quadratic, *r]
        out = {name: float(v) for name, v in zip(ACCEL_PARAM_NAMES, vals, strict=True)}
        return out | gyro_truth(self.cfg.gyro)

    def truth_arrays(self) -> dict[str, NDArray[np.float64]]:
        """Everything else the simulator knows, SI, body frame (lever arms, gyro errors, noise, site…)."""
        c = self.cfg
        out = {
            "accel_bias": np.asarray(c.accel.bias, float),
            "accel_scale": np.asarray(c.accel.scale, float),
            "accel_misalignment": misalignment_matrix(c.accel.misalignment),
            "accel_quadratic": np.asarray(c.accel.quadratic, float),
            "lever_arms": np.asarray(c.accel.lever_arms, float),
            "gyro_bias": np.asarray(c.gyro.bias, float),
            "gyro_scale": np.asarray(c.gyro.scale, float),
            "gyro_misalignment": misalignment_matrix(c.gyro.misalignment),
            "gyro_g_sensitivity": np.asarray(c.gyro.g_sensitivity, float),
            "accel_white": np.asarray(c.accel_noise.white, float),
            "accel_bias_instability": np.asarray(c.accel_noise.bias_instability, float),
            "accel_random_walk": np.asarray(c.accel_noise.random_walk, float),
            "gyro_white": np.asarray(c.gyro_noise.white, float),
            "gyro_bias_instability": np.asarray(c.gyro_noise.bias_instability, float),
            "gyro_random_walk": np.asarray(c.gyro_noise.random_walk, float),
            "mounting": np.asarray(c.mounting, float),
            "g": np.array(self._g),
            "gravity_anomaly": np.array(self._g_anomaly),
            "table_rate_error": self._rate_error.copy(),
            "table_azimuth_error": np.array(self._azimuth_error),
            "table_axis_tilt": self._axis_tilt.copy(),
            "latitude_error": np.array(self._latitude_error),
            "latitude": np.array(c.latitude),
            "earth_rate_enu": self._earth_n.copy(),
            "non_orthogonality": np.asarray(c.table.non_orthogonality, float) + self._axis_tilt,
            "wobble": np.array(c.table.wobble),
        }
        out.update({k: np.array(v) for k, v in self.clock_truth().items()})
        if c.periodic:
            out["periodic_frequency_hz"] = np.array([p.frequency_hz for p in c.periodic])
            out["periodic_amplitude"] = np.array([p.amplitude for p in c.periodic])
            out["periodic_phase"] = np.array([p.phase for p in c.periodic])
        return out

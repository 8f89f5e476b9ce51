"""A simulated turntable controller serving a Modbus TCP register map on 127.0.0.1, backed by the world.

:class:`ModbusTableServer` runs a real pymodbus 3.16 asyncio ``ModbusTcpServer`` in a background thread
with its own event loop. The datastore is a ``pymodbus.simulator.SimDevice`` with separate holding and input
register blocks laid out as a register-map file says (:mod:`drivers.modbus.register_map`; default: the shipped
tablebench map), and an ``action`` hook that

* refreshes the state input registers from ``world.table_state()`` when they are read,
* executes commands as the map's control scheme says (:mod:`drivers.modbus.register_map`, ``control``): a
  COMMAND register write, per-axis control words, or a start coil (MOVE → ``world.command_position`` or, one
  axis's control word, ``world.command_axis_position``; SPIN → ``world.command_rate``; STOP →
  ``world.command_stop``; CLEAR_FAULT / FAULT_RESET → ``world.clear_fault``), answering a refused command with
  Modbus exception 3 (illegal value: limits, bad command) or 4 (device failure: a fault is latched) and the
  reason in LAST_REJECT,
* feeds the watchdog on HEARTBEAT writes (``world.heartbeat`` too); a map without a heartbeat register is a
  PLC without a watchdog.

Safety behaviour of the controller (wall clock, independent of the world's bench-time watchdog):

* watchdog: once a heartbeat has been received (``watchdog_from_power_up``: from the server's start, as a
  strict PLC's), if no HEARTBEAT write arrives for ``watchdog_s`` seconds while motion is commanded
  (MOVE/SPIN since the last STOP), the table is stopped (``world.command_stop``), the fault
  COMMUNICATION_LOST is injected and WATCHDOG + FAULT are reported until a fault reset; a strict PLC also
  trips when a motion command arrives with the heartbeat already overdue (the command is refused);
* client disconnect while motion is commanded → ``world.command_stop``.

The limits are checked here as well as in the driver (a controller never trusts its client). The simulated
controller answers every unit id (pymodbus device id 0 = "all devices").
"""

from __future__ import annotations

import asyncio
import logging
import math
import threading
import time
from typing import TYPE_CHECKING, Any

from drivers.modbus.register_map import ModbusMap, map_with_word_order
from drivers.protocols import AxisMode, FaultCode, TableError, TableStatus, check_angles, check_spin

if TYPE_CHECKING:
    from drivers.sim.world import SimulatedWorld

log = logging.getLogger(__name__)


class ModbusTableServer:
    """Serve a SimulatedWorld's table on Modbus TCP (127.0.0.1).

    Parameters
    ----------
    world : SimulatedWorld
        Thread-safe world (shared with the serial unit server).
    port : int
        TCP port; 0 picks an ephemeral port (read :attr:`port`).
    word_order : {"big", "little"} or None
        Float word order of this controller (None: the map's).
    watchdog_s : float or None
        Wall-clock heartbeat timeout, s (None or 0 disables).
    host : str
    register_map : ModbusMap or None
        The layout served (None: the shipped tablebench map).
    watchdog_from_power_up : bool
        A strict PLC: the watchdog runs from the server's start, not from the first heartbeat.
    """

    def __init__(
        self,
        world: SimulatedWorld,
        port: int = 0,
        *,
        word_order: str | None = None,
        watchdog_s: float | None = None,
        host: str = "127.0.0.1",
        register_map: ModbusMap | None = None,
        watchdog_from_power_up: bool = False,
    ) -> None:
        m = map_with_word_order(register_map, word_order)
        self.map = m
        self.world = world
        self.word_order = m.word_order
        self.watchdog_s = float(watchdog_s) if watchdog_s and m.has_heartbeat else None
        self.strict = bool(watchdog_from_power_up)
        self.host = host
        self._limits = tuple(world.table_limits())
        self._last_hb: float | None = time.monotonic() if self.strict else None
        self._hr: dict[int, int] = {}  # the holding registers as written (the set-points a start coil uses)
        self._motion_commanded = False
        self._watchdog_latched = False
        self._last_reject = FaultCode.NONE
        self._hb_echo = 0
        self.connections = 0
        self._loop = asyncio.new_event_loop()
        self._server: Any = None
        self._watchdog_task: asyncio.Task[None] | None = None
        self._closed = False
        self._ready = threading.Event()
        self._error: BaseException | None = None
        self.port = 0
        self._thread = threading.Thread(target=self._run, args=(port,), name="sim-modbus-table", daemon=True)
        self._thread.start()
        if not self._ready.wait(timeout=5.0) or self._error is not None:
            self.close()
            raise RuntimeError(f"simulated Modbus controller failed to start on {host}:{port}: {self._error}")
        log.info("simulated Modbus controller on %s:%d", host, self.port)

    # ---- datastore ---------------------------------------------------------------------------------------------
    def _sizes(self) -> tuple[int, int]:
        m = self.map
        hr = max([a + m.size(n) for n, a in m.holding.items()] + [a + 1 for a in m.axis_command or ()])
        st = max(a + m.size(n) for n, a in m.state.items())
        return (max(hr, st), 1) if m.state_registers == "holding" else (hr, st)

    def _device(self) -> Any:
        from pymodbus.simulator import DataType, SimData, SimDevice

        m = self.map
        limits = []
        for lim in self._limits:
            limits += [
                lim.rate_max / m.rate_scale,
                lim.accel_max / m.rate_scale,
                math.nan if lim.position_min is None else lim.position_min / m.angle_scale,
                math.nan if lim.position_max is None else lim.position_max / m.angle_scale,
            ]
        n_hr, n_ir = self._sizes()
        hr, ir = [0] * n_hr, [0] * n_ir
        state = hr if m.state_registers == "holding" else ir
        a = m.state["limits"]
        state[a : a + m.size("limits")] = m.pack(limits)
        return SimDevice(
            id=0,
            simdata=(
                [
                    SimData(
                        0,
                        count=max([16, *(c + 1 for c in m.start_coils.values())]),
                        values=False,
                        datatype=DataType.BITS,
                    )
                ],
                [SimData(0, count=16, values=False, datatype=DataType.BITS)],
                [SimData(0, values=hr, datatype=DataType.REGISTERS)],
                [SimData(0, values=ir, datatype=DataType.REGISTERS)],
            ),
            action=self._action,
        )

    def _state_registers(self) -> dict[int, int]:
        """Address → register value of every state field but the limits, from the world's reading."""
        m = self.map
        s = self.world.table_state()
        status = s.status
        fault = FaultCode(s.fault_code)
        if self._watchdog_latched:
            status |= TableStatus.WATCHDOG | TableStatus.FAULT
            fault = fault or FaultCode.COMMUNICATION_LOST
        fields = {
            "time": m.pack(s.time / m.time_scale),
            "angles": m.pack([float(x) / m.angle_scale for x in s.angles]),
            "rates": m.pack([float(x) / m.rate_scale for x in s.rates]),
            "status": [m.status_to(status) & 0xFFFF],
            "fault_code": [m.fault_to(fault)],
            "mode": [m.modes[AxisMode(md).name] for md in s.modes],
            "last_reject": [m.fault_to(self._last_reject)],
            "heartbeat_echo": [self._hb_echo],
        }
        out: dict[int, int] = {}
        for name, regs in fields.items():
            for i, v in enumerate(regs):
                out[m.state[name] + i] = int(v)
        return out

    async def _action(
        self,
        function_code: int,
        start_address: int,
        address: int,
        count: int,
        registers: list[int],
        set_values: list[int] | list[bool] | None,
    ) -> Any:
        from pymodbus.constants import ExcCodes

        try:
            m = self.map
            state_fc = 4 if m.state_registers == "input" else 3
            lo, n = m.state_span()
            if function_code == state_fc and address < lo + n and address + count > lo:
                for a, v in self._state_registers().items():
                    if start_address <= a < start_address + len(registers):
                        registers[a - start_address] = v
                return None
            if function_code in (5, 15) and set_values:
                coil_action = {c: k for k, c in self.map.start_coils.items()}
                for i, v in enumerate(set_values):
                    action = coil_action.get(address + i)
                    if action is not None and v:
                        return self._execute(action, self._coil_axes(action))
                return None
            if function_code in (6, 16) and set_values:
                touched = range(address, address + count)
                for a, v in zip(touched, set_values, strict=False):
                    self._hr[a] = int(v)
                h = m.holding
                if "heartbeat" in h and h["heartbeat"] in touched:
                    self._last_hb = time.monotonic()
                    self._hb_echo = self._hr[h["heartbeat"]] & 0xFFFF
                    self.world.heartbeat()
                if h["fault_reset"] in touched and self._hr[h["fault_reset"]] == 1:
                    self._clear_fault()
                if m.start_coils:
                    return None
                if m.scheme == "per-axis":
                    assert m.axis_command is not None
                    hit = [i for i, w in enumerate(m.axis_command) if w in touched]
                    if hit:
                        acts = {self._hr[m.axis_command[i]] for i in hit}
                        if len(acts) != 1:
                            self._last_reject = FaultCode.BAD_COMMAND
                            return ExcCodes.ILLEGAL_VALUE
                        return self._execute_value(acts.pop(), tuple(hit))
                elif "command" in h and h["command"] in touched:
                    v = self._hr[h["command"]]
                    axes = (self._hr.get(h["command_axis"], 0),) if v == m.commands["spin"] else (0, 1, 2)
                    return self._execute_value(v, axes)
            return None
        except TableError as exc:
            log.info("simulated Modbus controller refused a command: %s", exc)
            fault = self._fault_code()
            if fault != FaultCode.NONE:
                self._last_reject = fault
                return ExcCodes.DEVICE_FAILURE
            return ExcCodes.ILLEGAL_VALUE
        except Exception:  # never let a bug kill the server task silently
            log.exception("simulated Modbus controller: internal error")
            return ExcCodes.DEVICE_FAILURE

    def _fault_code(self) -> FaultCode:
        """The latched fault (the controller's watchdog latch first, else the world's)."""
        if self._watchdog_latched:
            return FaultCode.COMMUNICATION_LOST
        try:
            return FaultCode(self.world.table_state().fault_code)
        except Exception:
            return FaultCode.NONE

    def _clear_fault(self) -> None:
        self.world.clear_fault()
        self._watchdog_latched = False
        self._last_reject = FaultCode.NONE

    def _coil_axes(self, action: str) -> tuple[int, ...]:
        """The axes a start coil acts on: per-axis, those whose control word holds the action; else a spin's
        ``command_axis`` or every axis."""
        m = self.map
        if m.scheme == "per-axis":
            assert m.axis_command is not None
            return tuple(i for i, w in enumerate(m.axis_command) if self._hr.get(w) == m.commands[action])
        return (self._hr.get(m.holding["command_axis"], 0),) if action == "spin" else (0, 1, 2)

    def _execute_value(self, value: int, axes: tuple[int, ...]) -> Any:
        from pymodbus.constants import ExcCodes

        if value == 0:
            return None
        action = {v: k for k, v in self.map.commands.items()}.get(value)
        if action is None:
            self._last_reject = FaultCode.BAD_COMMAND
            return ExcCodes.ILLEGAL_VALUE
        return self._execute(action, axes)

    def _values(self, name: str, k: int = 0, n: int | None = None) -> list[float]:
        m = self.map
        a = m.holding[name] + k
        return m.unpack([self._hr.get(a + i, 0) for i in range(n if n is not None else m.size(name))])

    def _execute(self, action: str, axes: tuple[int, ...]) -> Any:
        from pymodbus.constants import ExcCodes

        m = self.map
        if action == "stop":
            self.world.command_stop()
            self._motion_commanded = False
            return None
        if action == "clear_fault":
            self._clear_fault()
            return None
        if not axes:
            self._last_reject = FaultCode.BAD_COMMAND
            return ExcCodes.ILLEGAL_VALUE
        if self.strict and self.watchdog_s and not self._watchdog_latched:
            assert self._last_hb is not None
            if time.monotonic() - self._last_hb > self.watchdog_s:
                log.warning("simulated strict PLC: motion commanded with the heartbeat overdue (WATCHDOG)")
                self._trip()
        if self._watchdog_latched:
            self._last_reject = FaultCode.COMMUNICATION_LOST
            return ExcCodes.DEVICE_FAILURE
        if action == "move":
            self._last_reject = FaultCode.POSITION_LIMIT
            sp = [x * m.angle_scale for x in self._values("position_setpoint")]
            angles = check_angles(sp, self._limits)  # type: ignore[arg-type]
            if len(axes) == 3:
                self.world.command_position(angles)
            else:
                for ax in axes:
                    self.world.command_axis_position(ax, float(angles[ax]))
        else:  # spin
            self._last_reject = FaultCode.RATE_LIMIT
            for axis in axes:
                if axis > 2:
                    self._last_reject = FaultCode.BAD_COMMAND
                    return ExcCodes.ILLEGAL_VALUE
                rate = self._values("rate_setpoint", m.value_regs * axis, m.value_regs)[0] * m.rate_scale
                ax, r = check_spin(axis, rate, self._limits)  # type: ignore[arg-type]
                self.world.command_rate(ax, r)
        self._last_reject = FaultCode.NONE
        self._motion_commanded = True
        return None

    def _trip(self) -> None:
        """The watchdog trips: stop under control, latch COMMUNICATION_LOST."""
        self.world.command_stop()
        try:
            self.world.inject_fault(FaultCode.COMMUNICATION_LOST)
        except Exception:
            log.debug("world.inject_fault(COMMUNICATION_LOST) not supported", exc_info=True)
        self._watchdog_latched = True
        self._motion_commanded = False

    # ---- event loop thread -------------------------------------------------------------------------------------
    def _trace_connect(self, connected: bool) -> None:
        if connected:
            self.connections += 1
            return
        if self._motion_commanded and not self._closed:
            log.warning("simulated Modbus controller: client disconnected during motion; stopping the table")
            try:
                self.world.command_stop()
            except Exception:
                log.exception("stop after disconnect failed")
            self._motion_commanded = False

    async def _start(self, port: int) -> None:
        from pymodbus.server import ModbusTcpServer

        self._server = ModbusTcpServer(self._device(), address=(self.host, port), trace_connect=self._trace_connect)
        await self._server.serve_forever(background=True)
        self.port = int(self._server.transport.sockets[0].getsockname()[1])
        if self.watchdog_s:
            self._watchdog_task = asyncio.ensure_future(self._watchdog())

    async def _watchdog(self) -> None:
        assert self.watchdog_s is not None
        period = min(0.05, self.watchdog_s / 4)
        while True:
            await asyncio.sleep(period)
            if self._last_hb is None or self._watchdog_latched or not self._motion_commanded:
                continue
            if time.monotonic() - self._last_hb > self.watchdog_s:
                log.warning(
                    "simulated Modbus controller: no heartbeat for %.3g s; stopping the table (WATCHDOG)",
                    self.watchdog_s,
                )
                self._trip()

    def _run(self, port: int) -> None:
        asyncio.set_event_loop(self._loop)
        try:
            self._loop.run_until_complete(self._start(port))
        except BaseException as exc:  # report to the constructor
            self._error = exc
            self._ready.set()
            return
        self._ready.set()
        self._loop.run_forever()

    def _in_loop(self, coro: Any, timeout: float = 3.0) -> None:
        if self._loop.is_running():
            asyncio.run_coroutine_threadsafe(coro, self._loop).result(timeout=timeout)
        else:
            coro.close()

    async def _drop(self) -> None:
        if self._server is not None:
            for conn in list(self._server.active_connections.values()):
                conn.callback_disconnected(None)  # a local close skips pymodbus's disconnect callback
                conn.close()

    def drop_clients(self) -> None:
        """Close every client connection from the controller side (simulates a network failure)."""
        self._in_loop(self._drop())

    async def _shutdown(self) -> None:
        if self._watchdog_task is not None:
            self._watchdog_task.cancel()
        if self._server is not None:
            await self._server.shutdown()

    @property
    def watchdog_tripped(self) -> bool:
        """True while a watchdog trip is latched."""
        return self._watchdog_latched

    def close(self) -> None:
        """Shut the server down and join its thread (idempotent)."""
        if self._closed:
            return
        self._closed = True
        try:
            self._in_loop(self._shutdown())
        except Exception:
            log.debug("Modbus server shutdown", exc_info=True)
        if self._loop.is_running():
            self._loop.call_soon_threadsafe(self._loop.stop)
        self._thread.join(timeout=3.0)
        if not self._loop.is_running():
            self._loop.close()

    def __enter__(self) -> ModbusTableServer:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

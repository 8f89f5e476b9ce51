"""A simulated turntable controller serving the Modbus TCP register map on 127.0.0.1, backed by the world.

:class:`ModbusTableServer` runs a real pymodbus 3.16 asyncio ``ModbusTcpServer`` in a background thread
with its own event loop. The datastore is a ``pymodbus.simulator.SimDevice`` with separate holding and input
register blocks laid out as in :mod:`drivers.modbus_registers`, and an ``action`` hook that

* refreshes the state input registers from ``world.table_state()`` when they are read,
* executes COMMAND writes (MOVE → ``world.command_position``, SPIN → ``world.command_rate``, STOP →
  ``world.command_stop``, CLEAR_FAULT / FAULT_RESET → ``world.clear_fault``), answering a refused command with
  Modbus exception 3 (illegal value: limits, bad command) or 4 (device failure: a fault is latched) and the
  reason in LAST_REJECT,
* feeds the watchdog on HEARTBEAT writes (``world.heartbeat`` too).

Safety behaviour of the controller (wall clock, independent of the world's bench-time watchdog):

* watchdog: once a heartbeat has been received, if no HEARTBEAT write arrives for ``watchdog_s`` seconds
  while motion is commanded (MOVE/SPIN since the last STOP), the table is stopped
  (``world.command_stop``), the fault COMMUNICATION_LOST is injected and WATCHDOG + FAULT are reported until
  a fault reset;
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
from typing import Any

from drivers import modbus_registers as reg
from drivers.modbus_table import check_position, check_rate
from drivers.protocols import FaultCode, TableError, TableStatus

log = logging.getLogger(__name__)


class ModbusTableServer:
    """Serve a SimulatedWorld's table on Modbus TCP (127.0.0.1).

    Parameters
    ----------
    world : SimulatedWorld
        Thread-safe world (shared with the serial unit server).
    port : int
        TCP port; 0 picks an ephemeral port (read :attr:`port`).
    word_order : {"big", "little"}
        Float word order of this controller.
    watchdog_s : float or None
        Wall-clock heartbeat timeout, s (None or 0 disables).
    host : str
    """

    def __init__(
        self,
        world: Any,
        port: int = 0,
        *,
        word_order: reg.WordOrder = "big",
        watchdog_s: float | None = None,
        host: str = "127.0.0.1",
    ) -> None:
        reg._check_order(word_order)
        self.world = world
        self.word_order: reg.WordOrder = word_order
        self.watchdog_s = float(watchdog_s) if watchdog_s else None
        self.host = host
        self._limits = tuple(world.table_limits())
        self._last_hb: float | None = None
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
    def _device(self) -> Any:
        from pymodbus.simulator import DataType, SimData, SimDevice

        limits = []
        for lim in self._limits:
            limits += [
                lim.rate_max,
                lim.accel_max,
                math.nan if lim.position_min is None else lim.position_min,
                math.nan if lim.position_max is None else lim.position_max,
            ]
        ir = [0] * reg.IR_COUNT
        ir[reg.IR_LIMITS : reg.IR_LIMITS + reg.IR_LIMITS_COUNT] = reg.pack_float64(limits, self.word_order)
        return SimDevice(
            id=0,
            simdata=(
                [SimData(0, count=16, values=False, datatype=DataType.BITS)],
                [SimData(0, count=16, values=False, datatype=DataType.BITS)],
                [SimData(0, values=[0] * reg.HR_COUNT, datatype=DataType.REGISTERS)],
                [SimData(0, values=ir, datatype=DataType.REGISTERS)],
            ),
            action=self._action,
        )

    def _state_registers(self) -> list[int]:
        s = self.world.table_state()
        status = int(s.status)
        fault = int(s.fault_code)
        if self._watchdog_latched:
            status |= int(TableStatus.WATCHDOG | TableStatus.FAULT)
            fault = fault or int(FaultCode.COMMUNICATION_LOST)
        out = reg.pack_float64([s.time, *map(float, s.angles), *map(float, s.rates)], self.word_order)
        out += [status & 0xFFFF, fault, *(int(m) for m in s.modes), int(self._last_reject), self._hb_echo]
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
            if function_code == 4:
                if address < reg.IR_STATE_COUNT:
                    regs = self._state_registers()
                    registers[0 : reg.IR_STATE_COUNT] = regs
                return None
            if function_code in (6, 16) and set_values:
                image = list(registers)
                off = address - start_address
                image[off : off + count] = [int(v) for v in set_values]
                touched = range(address, address + count)
                if reg.HR_HEARTBEAT in touched:
                    self._last_hb = time.monotonic()
                    self._hb_echo = image[reg.HR_HEARTBEAT] & 0xFFFF
                    self.world.heartbeat()
                if reg.HR_FAULT_RESET in touched and image[reg.HR_FAULT_RESET] == 1:
                    self._clear_fault()
                if reg.HR_COMMAND in touched:
                    return self._execute(image)
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

    def _execute(self, image: list[int]) -> Any:
        from pymodbus.constants import ExcCodes

        try:
            cmd = reg.Command(image[reg.HR_COMMAND])
        except ValueError:
            self._last_reject = FaultCode.BAD_COMMAND
            return ExcCodes.ILLEGAL_VALUE
        if cmd == reg.Command.STOP:
            self.world.command_stop()
            self._motion_commanded = False
            return None
        if cmd == reg.Command.CLEAR_FAULT:
            self._clear_fault()
            return None
        if cmd == reg.Command.NONE:
            return None
        if self._watchdog_latched:
            self._last_reject = FaultCode.COMMUNICATION_LOST
            return ExcCodes.DEVICE_FAILURE
        if cmd == reg.Command.MOVE:
            self._last_reject = FaultCode.POSITION_LIMIT
            sp = image[reg.HR_POSITION_SETPOINT : reg.HR_POSITION_SETPOINT + 12]
            angles = check_position(reg.unpack_float64(sp, self.word_order), self._limits)  # type: ignore[arg-type]
            self.world.command_position(angles)
        else:  # SPIN
            self._last_reject = FaultCode.RATE_LIMIT
            axis = image[reg.HR_COMMAND_AXIS]
            if axis > 2:
                self._last_reject = FaultCode.BAD_COMMAND
                return ExcCodes.ILLEGAL_VALUE
            a = reg.HR_RATE_SETPOINT + reg.F64_REGS * axis
            rate = reg.unpack_float64(image[a : a + reg.F64_REGS], self.word_order)[0]
            ax, r = check_rate(axis, rate, self._limits)  # type: ignore[arg-type]
            self.world.command_rate(ax, r)
        self._last_reject = FaultCode.NONE
        self._motion_commanded = True
        return None

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
                self.world.command_stop()
                try:
                    self.world.inject_fault(FaultCode.COMMUNICATION_LOST)
                except Exception:
                    log.debug("world.inject_fault(COMMUNICATION_LOST) not supported", exc_info=True)
                self._watchdog_latched = True
                self._motion_commanded = False

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

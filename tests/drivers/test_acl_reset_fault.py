"""A latched ACUTROL interlock fault needs an operator's acknowledgement (``tablebench table reset-fault``),
which says what the fault was; the simulated ACUTROL (ACL in memory and over pyvisa-py on loopback)."""

from __future__ import annotations

import io
import math

import pytest

from benches import factory
from benches.bench_config import load_bench
from benches.cli.commands import table as cmd
from drivers.protocols import FaultCode, TableError
from tests.simbench import SIM


@pytest.mark.parametrize("transport", ["in-process", "loopback"])
def test_latched_fault_requires_reset_fault(transport):
    bench = factory.open_table(load_bench(SIM), seed=3, transport=transport)
    try:
        out = io.StringIO()
        assert cmd.execute(bench, "move", ((math.radians(5), 0.0, 0.0),), out=out) == 0
        bench.world.inject_fault(FaultCode.AMPLIFIER)
        with pytest.raises(TableError, match="reset-fault"):
            cmd.execute(bench, "move", ((0.0, 0.0, 0.0),), out=out)
        with pytest.raises(TableError, match="reset-fault"):  # a second try does not reset it either
            cmd.execute(bench, "spin", (2, math.radians(5)), out=out)
        out = io.StringIO()
        assert cmd.execute(bench, "status", (), out=out) == 0
        assert "fault: interlock fault latched" in out.getvalue() and "tablebench table reset-fault" in out.getvalue()
        out = io.StringIO()
        assert cmd.execute(bench, "reset-fault", (), out=out) == 0
        text = out.getvalue()
        assert "acknowledged and reset: interlock fault latched" in text and "'Fault'" in text
        out = io.StringIO()
        assert cmd.execute(bench, "move", ((0.0, 0.0, 0.0),), out=out) == 0 and "settled" in out.getvalue()
        out = io.StringIO()
        assert cmd.execute(bench, "reset-fault", (), out=out) == 0 and "no fault is latched" in out.getvalue()
    finally:
        bench.close()

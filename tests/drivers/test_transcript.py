"""The transcript helper itself: a mismatch, an extra request and a missing one all fail; Modbus PDUs are the
examples of the Modbus Application Protocol specification V1.1b3 (§6.4, §6.12)."""

from __future__ import annotations

import pytest

from drivers.protocols import LinkError
from tests.drivers.transcript import (
    ModbusTranscript,
    expected_protocol,
    h,
    read_input,
    transcript_of,
    write_registers,
)


class Echo:
    def __init__(self, link):
        self.link = link

    def ask(self, q):
        return self.link.query(q)


def test_message_transcript_passes_and_fails():
    with expected_protocol(Echo, [("*IDN?", "maker,model,0,1")]) as e:
        assert e.ask("*IDN?") == "maker,model,0,1"
        assert transcript_of(e).sent == ["*IDN?"]
    with pytest.raises(AssertionError, match="the protocol says"), expected_protocol(Echo, [("*IDN?", "x")]) as e:
        e.ask("*idn?")
    with pytest.raises(AssertionError, match="never sent"), expected_protocol(Echo, [("A", "1"), ("B", "2")]) as e:
        e.ask("A")
    with pytest.raises(AssertionError, match="unexpected"), expected_protocol(Echo, [("A", "1")]) as e:
        e.ask("A")
        e.ask("A")
    with pytest.raises(LinkError, match="no reply"), expected_protocol(Echo, [("A", None)]) as e:
        e.ask("A")


def test_modbus_pdus_are_the_specification_examples():
    # §6.4 read input register 9 (address 8), count 1 → 04 00 08 00 01; response 04 02 00 0A
    assert read_input(8, [10]) == (h("04 00 08 00 01"), h("04 02 00 0A"))
    # §6.12 write registers 2 and 3 (address 1) with 000A, 0102
    assert write_registers(1, [0x000A, 0x0102]) == (h("10 00 01 00 02 04 00 0A 01 02"), h("10 00 01 00 02"))
    c = ModbusTranscript([read_input(8, [10]), (h("10 00 01 00 02 04 00 0A 01 02"), h("90 04"))])
    assert c.read_input_registers(8, count=1).registers == [10]
    r = c.write_registers(1, [10, 0x0102])
    assert r.isError() and r.exception_code == 4
    c.done()

"""Exact bytes of the Ideal Aerosmith driver, written from the public command set (docs/protocols/ideal-aerosmith.md:
the ``aerosmith`` package sends the three letters and the number with nothing appended, and a command is
accepted when the reply is the prompt CR LF > CR LF alone), never from the simulator; the one transcript helper."""

from __future__ import annotations

import math

import numpy as np
import pytest

from drivers.aerosmith import AerosmithSettings, AerosmithTable
from drivers.protocols import AxisLimits, AxisMode, LinkError, TableError, TableStatus
from tests.drivers.transcript import ByteTranscript, expected_protocol

R = math.radians
P = b"\r\n>\r\n"
ABSENT = AxisLimits.absent_axis()
LIMITS = (ABSENT, ABSENT, AxisLimits(rate_max=R(360), accel_max=R(80)))


def table(link, **settings):
    return AerosmithTable(link, LIMITS, settings=AerosmithSettings(**settings), clock=lambda: 0.0)


def test_spin_read_stop():
    pairs = [
        (b"SRV1", P),
        (b"ACL80", P),
        (b"JOG-12.5", P),
        (b"POS?", b"123.250000\r\n" + P),
        (b"RAT?", b"-12.500000\r\n" + P),
        (b"STO", P),
    ]
    with expected_protocol(table, pairs) as t:
        t.spin(2, R(-12.5))
        s = t.read_state()
        assert s.angles[2] == pytest.approx(R(123.25)) and s.rates[2] == pytest.approx(R(-12.5))
        assert s.modes == (AxisMode.STOP, AxisMode.STOP, AxisMode.RATE) and s.status & TableStatus.AT_RATE
        t.stop()


def test_home_and_a_terminator_setting():
    pairs = [(b"SRV1\r", P), (b"HOM\r", P), (b"POS?\r", b"0.000000\r\n" + P), (b"RAT?\r", b"0.000000\r\n" + P)]
    with expected_protocol(lambda link: table(link, command_terminator="\r"), pairs) as t:
        t.move_to([0.0, 0.0, 0.0])
        assert t.read_state().status & TableStatus.IN_POSITION


def test_demands_the_table_cannot_do_send_nothing():
    with expected_protocol(table, [], link=ByteTranscript) as t:
        with pytest.raises(TableError, match="moves only home.*nothing was sent"):
            t.move_to([0.0, 0.0, R(45)])
        with pytest.raises(TableError, match="has no outer axis.*nothing was sent"):
            t.move_to([R(10), 0.0, 0.0])
        with pytest.raises(TableError, match="has no middle axis.*nothing was sent"):
            t.spin(1, R(5))
        with pytest.raises(TableError, match="exceeds the inner axis limit 360.*nothing was sent"):
            t.spin(2, R(361))


def test_controller_text_before_the_prompt_is_a_refusal_and_no_prompt_a_dead_link():
    with expected_protocol(table, [(b"SRV1", P), (b"ACL80", P), (b"JOG10", b"ERROR servo fault\r\n" + P)]) as t:
        with pytest.raises(TableError, match="refused 'JOG10': 'ERROR servo fault'"):
            t.spin(2, R(10))
    with expected_protocol(table, [(b"STO", b"")]) as t:
        with pytest.raises(LinkError, match="no prompt after 'STO'.*turntable.aerosmith.prompt"):
            t.stop()


def test_an_axis_the_table_has_not_must_be_absent():
    with pytest.raises(ValueError, match="one axis"):
        AerosmithTable(ByteTranscript([]), (LIMITS[2], ABSENT, LIMITS[2]))
    np.testing.assert_equal(ABSENT.absent and not LIMITS[2].absent, True)

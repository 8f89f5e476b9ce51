"""Exact bytes of the Espec driver (RS-232, no address; every line ends CR LF), from the thermal-chamber spec."""

from __future__ import annotations

import pytest

from analysis.units import celsius_to_kelvin as C
from drivers.chamber.base import ChamberError, ChamberLinkError, ChamberSettings
from drivers.chamber.espec import EspecChamber, EspecSettings
from drivers.chamber.safety import leave_safe
from drivers.chamber.stream import LineChannel
from tests.drivers.chamber.script import FakeClock, ScriptedStream, h

TEMP_Q = (h("54 45 4D 50 3F 0D 0A"), b"26.4,0.0,140.0,-50.0\r\n")
SET_M20 = (h("54 45 4D 50 2C 20 53 2D 32 30 2E 30 0D 0A"), b"OK:TEMP, S-20.0\r\n")


def espec(script, **kw):
    s = ScriptedStream(script)
    link = LineChannel(s, "Espec", timeout=1.0, clock=FakeClock())
    return EspecChamber(link, ChamberSettings(), EspecSettings(**kw)), s


def test_temp_query_and_mon_with_empty_humidity():
    drv, s = espec([TEMP_Q, (b"MON?\r\n", b"23.0,,CONSTANT,0\r\n")])
    r = drv.read()
    assert r.air == pytest.approx(C(26.4)) and r.setpoint == pytest.approx(C(0.0))
    assert r.running is True and r.alarm is False
    s.done()


def test_mon_with_humidity_and_without_the_field():
    drv, s = espec([(b"MON?\r\n", b"24.1,100,CONSTANT,0\r\n"), (b"MON?\r\n", b"24.1,STANDBY,2\r\n")])
    assert drv.read_monitor() == ("CONSTANT", 0)
    assert drv.read_monitor() == ("STANDBY", 2)
    s.done()


def test_set_point_minus_20_spaced_form_and_read_back():
    back = (b"TEMP?\r\n", b"-19.8,-20.0,140.0,-50.0\r\n")
    drv, s = espec([SET_M20, back])
    assert drv.set_setpoint(C(-20.0)) == pytest.approx(C(-20.0))
    s.done()


def test_set_point_compact_form_and_rs485_address():
    drv, s = espec(
        [(b"1,TEMP,S25.0\r\n", b"OK:1,TEMP,S25.0\r\n"), (b"1,TEMP?\r\n", b"24.0,25.0,140.0,-50.0\r\n")],
        setpoint_form="compact",
        address=1,
    )
    drv.set_setpoint(C(25.0))
    s.done()


def test_echo_with_spaces_is_accepted_a_wrong_echo_is_not():
    drv, s = espec([(b"MODE,CONSTANT\r\n", b"OK : 1, MODE, CONSTANT\r\n")])
    drv.setting("MODE,CONSTANT")
    drv, s = espec([(b"MODE,CONSTANT\r\n", b"OK:MODE,STANDBY\r\n")])
    with pytest.raises(ChamberLinkError, match="acknowledged"):
        drv.setting("MODE,CONSTANT")


def test_start_powers_on_an_off_chamber():
    drv, s = espec(
        [
            (b"MODE?\r\n", b"OFF\r\n"),
            (b"POWER,ON\r\n", b"OK:POWER,ON\r\n"),
            (b"MODE,CONSTANT\r\n", b"OK:MODE,CONSTANT\r\n"),
        ]
    )
    drv.start()
    s.done()


def test_stop_is_standby_and_optionally_power_off():
    drv, s = espec(
        [(b"MODE,STANDBY\r\n", b"OK:MODE,STANDBY\r\n"), (b"POWER,off\r\n", b"OK:POWER,off\r\n")], power_off_on_stop=True
    )
    drv.stop()
    s.done()


def test_unknown_command_na_reply():
    drv, s = espec([(b"FOO?\r\n", b"NA:CMD ERR\r\n")])
    with pytest.raises(ChamberError, match="CMD ERR"):
        drv.monitor("FOO?")


def test_identify():
    drv, s = espec([(b"TYPE?\r\n", b"T,T,S2,160.0\r\n"), (b"ROM?\r\n", b"P3 1.02\r\n")])
    assert "S2" in drv.identify()
    s.done()


def test_exit_path_safe_setpoint_then_standby():
    drv, s = espec(
        [
            (b"TEMP, S25.0\r\n", b"OK:TEMP, S25.0\r\n"),
            (b"TEMP?\r\n", b"-10.0,25.0,140.0,-50.0\r\n"),
            (b"MODE,STANDBY\r\n", b"OK:MODE,STANDBY\r\n"),
        ]
    )
    assert leave_safe(drv) == []
    s.done()


def test_silence_is_a_link_error():
    drv, _ = espec([(b"TEMP?\r\n", None)])
    with pytest.raises(ChamberLinkError, match="no complete reply"):
        drv.read()

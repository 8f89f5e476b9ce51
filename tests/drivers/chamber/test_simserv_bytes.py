"""Exact bytes of the simserv driver (separator B6, requests end CR, replies CR LF), from the thermal-chamber
spec."""

from __future__ import annotations

import pytest

from analysis.units import celsius_to_kelvin as C
from drivers.chamber.base import ChamberError, ChamberLinkError, ChamberSettings
from drivers.chamber.safety import leave_safe
from drivers.chamber.simserv import SimservChamber, SimservSettings
from tests.drivers.chamber.script import FakeClock, ScriptedStream, h

SET_M20 = (h("31 31 30 30 31 B6 31 B6 31 B6 2D 32 30 2E 30 0D"), h("31 0D 0A"))
READ_PV = (h("31 31 30 30 34 B6 31 B6 31 0D"), h("31 B6 32 33 2E 34 0D 0A"))
START = (h("31 34 30 30 31 B6 31 B6 31 B6 31 0D"), h("31 0D 0A"))
STOP = (h("31 34 30 30 31 B6 31 B6 31 B6 30 0D"), h("31 0D 0A"))


def sim(script, **kw):
    s = ScriptedStream(script)
    clock = FakeClock()
    kw.setdefault("run_pause", 1.0)
    drv = SimservChamber(s, ChamberSettings(), SimservSettings(**kw), clock=clock, sleep=clock.sleep)
    return drv, s, clock


def test_set_point_minus_20_and_read_back():
    back = (b"11002\xb61\xb61\r", b"1\xb6-20.0\r\n")
    drv, s, _ = sim([SET_M20, back])
    assert drv.set_setpoint(C(-20.0)) == pytest.approx(C(-20.0))
    s.done()


def test_read_pv_sp_run_status():
    sp = (b"11002\xb61\xb61\r", b"1\xb625.0\r\n")
    run = (b"14003\xb61\xb61\r", b"1\xb61\r\n")
    status = (b"10012\xb61\r", b"1\xb611\r\n")  # 3 running + 8 alarm
    drv, s, _ = sim([sp, READ_PV, run, status])
    r = drv.read()
    assert r.air == pytest.approx(C(23.4)) and r.setpoint == pytest.approx(C(25.0))
    assert r.running is True and r.alarm is True
    s.done()


def test_start_and_stop_pause_as_the_client_does():
    drv, s, clock = sim([START, STOP])
    drv.start()
    drv.stop()
    assert clock.slept == [1.0, 1.0]
    s.done()


def test_leading_separator_variant():
    drv, s, _ = sim([(b"\xb611004\xb61\xb61\r", b"1\xb623.4\r\n")], leading_separator=True)
    assert drv.request(11004, "1") == ["23.4"]
    s.done()


def test_unknown_command_negative_code():
    drv, s, _ = sim([(b"12345\xb61\r", h("2D 35 0D 0A"))])
    with pytest.raises(ChamberError, match="code -5 \\(unknown command\\)"):
        drv.request(12345)


def test_read_failed_text_is_an_error():
    drv, s, _ = sim([READ_PV[0:1] + (b"read failed\r\n",)])
    with pytest.raises(ChamberError, match="read failed"):
        drv.request(11004, "1")


def test_exit_path_safe_setpoint_then_stop():
    set25 = (b"11001\xb61\xb61\xb625.0\r", b"1\r\n")
    back = (b"11002\xb61\xb61\r", b"1\xb625.0\r\n")
    drv, s, _ = sim([set25, back, STOP])
    assert leave_safe(drv) == []
    s.done()


def test_exit_path_with_warm_up_waits_for_the_air():
    from dataclasses import replace

    set25 = (b"11001\xb61\xb61\xb625.0\r", b"1\r\n")
    back = (b"11002\xb61\xb61\r", b"1\xb625.0\r\n")

    def reading(pv):
        return [
            (b"11002\xb61\xb61\r", b"1\xb625.0\r\n"),
            (b"11004\xb61\xb61\r", f"1\xb6{pv}\r\n".encode("latin-1")),
            (b"14003\xb61\xb61\r", b"1\xb61\r\n"),
            (b"10012\xb61\r", b"1\xb63\r\n"),
        ]

    drv, s, clock = sim([set25, back, *reading("-5.0"), *reading("12.0"), STOP], run_pause=0.0)
    drv.settings = replace(drv.settings, warm_up_below=C(10.0))
    waits = []
    assert leave_safe(drv, wait=waits.append, clock=clock) == []
    assert waits == [10.0]
    s.done()


def test_silence_is_a_link_error():
    drv, _, _ = sim([(READ_PV[0], None)])
    with pytest.raises(ChamberLinkError):
        drv.request(11004, "1")

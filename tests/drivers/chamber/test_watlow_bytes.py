"""Exact bytes of the Watlow F4 / F4T drivers: every exchange the thermal-chamber spec lists (RTU address 1,
dp = 1; TCP), plus the ones a reading and the exit path need, with CRCs from pymodbus' own encoder."""

from __future__ import annotations

import pytest

from analysis.units import celsius_to_kelvin as C
from drivers.chamber.base import ChamberError, ChamberLinkError, ChamberSettings
from drivers.chamber.modbus_rtu import ModbusMaster, crc16
from drivers.chamber.safety import leave_safe
from drivers.chamber.watlow import WatlowF4, WatlowF4Settings, WatlowF4T, WatlowF4TSettings
from tests.drivers.chamber.script import FakeClock, ScriptedStream, h, rtu

READ_PV = (h("01 03 00 64 00 01 C5 D5"), h("01 03 02 00 EB F8 0B"))
SET_M20 = (h("01 06 01 2C FF 38 09 DD"), h("01 06 01 2C FF 38 09 DD"))
READ_SP_M20 = (h("01 03 01 2C 00 01 44 3F"), h("01 03 02 FF 38 F8 66"))
READ_606 = (h("01 03 02 5E 00 01 E4 60"), h("01 03 02 00 01 79 84"))
TERMINATE = (h("01 06 04 C1 00 01 18 C6"), h("01 06 04 C1 00 01 18 C6"))


def f4(script, framing="rtu", decimals=1, settings=None, **kw):
    s = ScriptedStream(script)
    clock = FakeClock()
    m = ModbusMaster(s, framing, 1, timeout=1.0, send_delay=0.03, clock=clock, sleep=clock.sleep)
    drv = WatlowF4(m, settings or ChamberSettings(), WatlowF4Settings(decimals=decimals, **kw))
    return drv, s, clock


def test_crc_check_values():
    assert crc16(b"123456789") == 0x4B37
    assert crc16(h("01 03 00 00 00 01")).to_bytes(2, "little") == h("84 0A")


def test_connect_reads_decimals_and_units():
    drv, s, _ = f4([READ_606, (rtu("01 03 03 85 00 01"), rtu("01 03 02 00 01"))], decimals=None)
    drv.connect()
    assert drv.decimals == 1
    s.done()


def test_fahrenheit_controller_is_refused():
    drv, s, _ = f4([READ_606, (rtu("01 03 03 85 00 01"), rtu("01 03 02 00 00"))], decimals=None)
    with pytest.raises(ChamberError, match="901"):
        drv.connect()


def test_read_pv_sp_error_state():
    sp = (h("01 03 01 2C 00 01 44 3F"), rtu("01 03 02 00 FA"))  # 25.0
    err = (rtu("01 03 00 65 00 01"), rtu("01 03 02 00 00"))
    state = (rtu("01 03 00 C8 00 01"), rtu("01 03 02 00 01"))
    drv, s, clock = f4([READ_PV, sp, err, state])
    r = drv.read()
    assert r.air == pytest.approx(C(23.5)) and r.setpoint == pytest.approx(C(25.0))
    assert r.alarm is False and r.running is None and "constant" in r.detail
    assert clock.slept == [0.03] * 4  # Watlow's recommended delay after each request
    s.done()


def test_read_pv_with_function_04_and_input_error():
    pv = (rtu("01 04 00 64 00 01"), rtu("01 04 02 FF 38"))
    sp = (rtu("01 03 01 2C 00 01"), rtu("01 03 02 FF 38"))
    err = (rtu("01 03 00 65 00 01"), rtu("01 03 02 00 01"))
    state = (rtu("01 03 00 C8 00 01"), rtu("01 03 02 00 02"))
    drv, s, _ = f4([pv, sp, err, state], pv_function=4)
    r = drv.read()
    assert r.air == pytest.approx(C(-20.0)) and r.alarm is True and "profile running" in r.detail
    s.done()


def test_set_point_minus_20_is_written_and_read_back():
    drv, s, _ = f4([SET_M20, READ_SP_M20])
    assert drv.set_setpoint(C(-20.0)) == pytest.approx(C(-20.0))
    s.done()


def test_set_point_rounds_to_nearest_count():
    # -19.96 °C at dp 1 → -200 counts (truncation would give -199)
    drv, s, _ = f4([SET_M20, READ_SP_M20])
    drv.set_setpoint(C(-19.96))
    s.done()


def test_set_point_is_clamped_to_the_bench_limits():
    settings = ChamberSettings(setpoint_min=C(-20.0), setpoint_max=C(60.0))
    drv, s, _ = f4([SET_M20, READ_SP_M20], settings=settings)
    assert drv.set_setpoint(C(-45.0)) == pytest.approx(C(-20.0))
    s.done()


def test_read_back_mismatch_is_an_error():
    drv, s, _ = f4([SET_M20, (h("01 03 01 2C 00 01 44 3F"), rtu("01 03 02 00 FA"))])
    with pytest.raises(ChamberError, match="read back"):
        drv.set_setpoint(C(-20.0))


def test_stop_terminates_profile_and_run_event():
    event_off = (rtu("01 06 07 DA 00 00"), rtu("01 06 07 DA 00 00"))  # event 2 → register 2010
    drv, s, _ = f4([TERMINATE, event_off], run_event=2)
    drv.stop()
    s.done()


def test_exception_to_a_read():
    drv, s, _ = f4([(h("01 03 00 64 00 01 C5 D5"), h("01 83 02 C0 F1"))])
    with pytest.raises(ChamberError, match="exception 2 \\(illegal data address\\)"):
        drv.read()


def test_bad_crc_and_silence_are_link_errors():
    drv, _, _ = f4([(h("01 03 00 64 00 01 C5 D5"), h("01 03 02 00 EB F8 0C"))])
    with pytest.raises(ChamberLinkError, match="CRC"):
        drv.read()
    drv, _, _ = f4([(h("01 03 00 64 00 01 C5 D5"), None)])
    with pytest.raises(ChamberLinkError, match="no complete reply"):
        drv.read()


def test_tcp_read_pv():
    pv = (h("00 01 00 00 00 06 01 03 00 64 00 01"), h("00 01 00 00 00 05 01 03 02 00 EB"))
    sp = (h("00 02 00 00 00 06 01 03 01 2C 00 01"), h("00 02 00 00 00 05 01 03 02 00 FA"))
    err = (h("00 03 00 00 00 06 01 03 00 65 00 01"), h("00 03 00 00 00 05 01 03 02 00 00"))
    state = (h("00 04 00 00 00 06 01 03 00 C8 00 01"), h("00 04 00 00 00 05 01 03 02 00 00"))
    drv, s, _ = f4([pv, sp, err, state], framing="tcp")
    assert drv.read().air == pytest.approx(C(23.5))
    s.done()


def test_exit_path_safe_setpoint_then_terminate():
    set25 = (rtu("01 06 01 2C 00 FA"), rtu("01 06 01 2C 00 FA"))
    read25 = (rtu("01 03 01 2C 00 01"), rtu("01 03 02 00 FA"))
    drv, s, _ = f4([set25, read25, TERMINATE])
    assert leave_safe(drv) == []
    s.done()


def test_exit_path_stops_even_if_the_set_point_is_refused():
    refused = (rtu("01 06 01 2C 00 FA"), rtu("01 86 03"))
    drv, s, _ = f4([refused, TERMINATE])
    problems = leave_safe(drv)
    assert len(problems) == 1 and "safe set point" in problems[0]
    s.done()


def f4t(script, order="low_first"):
    s = ScriptedStream(script)
    clock = FakeClock()
    m = ModbusMaster(s, "rtu", 1, timeout=1.0, clock=clock, sleep=clock.sleep)
    return WatlowF4T(m, ChamberSettings(), WatlowF4TSettings(word_order=order)), s


def test_f4t_set_point_25():
    write = (h("01 10 0A DE 00 02 04 00 00 41 C8 30 19"), h("01 10 0A DE 00 02 22 2A"))
    back = (rtu("01 03 0A DE 00 02"), rtu("01 03 04 00 00 41 C8"))
    drv, s = f4t([write, back])
    assert drv.set_setpoint(C(25.0)) == pytest.approx(C(25.0))
    s.done()


def test_f4t_read_pv_both_word_orders():
    pv = (h("01 03 0B 04 00 02 87 EE"), h("01 03 04 00 00 41 BC CB D2"))
    sp = (rtu("01 03 0A DE 00 02"), rtu("01 03 04 00 00 41 C8"))
    state = (rtu("01 03 40 B8 00 01"), rtu("01 03 02 00 95"))
    status = (rtu("01 03 00 5A 00 01"), rtu("01 03 02 00 8A"))  # 138 = OK
    drv, s = f4t([pv, sp, state, status])
    r = drv.read()
    assert r.air == pytest.approx(C(23.5)) and r.setpoint == pytest.approx(C(25.0)) and r.detail == "profile running"
    assert r.alarm is False
    s.done()
    pv_hi = (rtu("01 03 0B 04 00 02"), rtu("01 03 04 41 BC 00 00"))
    sp_hi = (rtu("01 03 0A DE 00 02"), rtu("01 03 04 41 C8 00 00"))
    failed = (rtu("01 03 00 5A 00 01"), rtu("01 03 02 00 20"))  # 32 = fail
    drv, s = f4t([pv_hi, sp_hi, state, failed], order="high_first")
    r = drv.read()
    assert r.air == pytest.approx(C(23.5)) and r.alarm is True
    s.done()


def test_f4t_stop_terminates_profile():
    drv, s = f4t([(rtu("01 06 40 B6 00 94"), rtu("01 06 40 B6 00 94"))])
    drv.stop()
    s.done()

"""The simulated ACUTROL3000: strict ACL parser, reply profiles, status registers, interlocks, limits."""

from __future__ import annotations

import math

import pytest

from drivers.acutrol.settings import AclSettings
from drivers.protocols import AxisLimits, AxisMode, FaultCode
from drivers.sim.acl_controller import AclController
from drivers.sim.config import SimConfig, TableModel
from drivers.sim.world import SimulatedWorld

LIMITS = (
    AxisLimits(rate_max=math.radians(300), accel_max=math.radians(100)),
    AxisLimits(rate_max=math.radians(200), accel_max=math.radians(100), position_min=-2.9, position_max=2.9),
    AxisLimits(rate_max=math.radians(200), accel_max=math.radians(100)),
)

# what the public lab client (IEAv-EFO/acutrol3000) sends to a real ACUTROL3000
PUBLIC_CLIENT = [
    ":Interlock:Reset",
    ":int:close 1",
    ":mode:rate 1",
    ":dem:rate 1,0",
    "*idn?",
    ":mode:off 1",
    ":read:pos? 1;rate? 1;acc? 1",
    ":m:p ALL",
    ":d:r 1,10",
    ":limit:rate? pos,1",
]
MISSPELT = [
    ":Demand:Posn 3,10.5",  # spelling (TM-8004 §2.1)
    ":Dem;Pos 3,10.5",  # misuse of the semicolon
    ":D:P,3,10.5",  # comma between command and data
    ":mod:rate 1",  # neither long (MODE) nor one-letter (M)
    ":Mode:Rat 1",
    ":read:pos? 4",  # no axis 4
    ":read:pos? ALL",  # ALL not allowed in a query
    ":mode 1,a",  # ambiguous enumeration (ARate / Abort)
    ":stop",  # the invented dialect's stop: not ACL
    ":fault:reset",
    "*RST",  # not implemented on the controller
    ":dem:pos 1,12345678901234567890123456789",  # more than 28 characters
    ":int:close 1;",  # empty command
]


def make(profile="tcp", **kw):
    w = SimulatedWorld(SimConfig(table=TableModel(limits=LIMITS, watchdog=None)), 4)
    return w, AclController(w, AclSettings(reply_profile=profile, **kw))


def test_public_client_strings_are_accepted():
    w, c = make()
    c.handle(":int:close 2;close 3")
    for msg in PUBLIC_CLIENT:
        reply = c.handle(msg)
        assert c.status_byte() == 0 and not c.errors, (msg, list(c.errors))
        assert len(reply) == 1
    assert c.handle("*idn?")[0].split(",")[1] == "Acutrol3000"
    assert c.handle(":limit:rate? pos,1") == [f"{0.9 * 300:.4f}"]  # position mode cruises at slew_fraction·rate_max


@pytest.mark.parametrize("msg", MISSPELT)
def test_misspellings_are_rejected_by_status_bits_not_text(msg):
    w, c = make()
    c.handle(":int:close 1;close 2;close 3")
    before = list(c.mode)
    reply = c.handle(msg)
    assert reply == [""]  # tcp: no error text, just the line
    stb = int(c.handle(":Status:STB?")[0])
    assert stb & 0x80 and stb & 0x40  # EQ + MSS
    assert int(c.handle("*ESR?")[0]) & 0b100  # bad device-dependent message
    text = c.handle(":Status:MSG? QERROR")[0]
    assert text and not c.errors and c.mode == before


def test_whole_message_rejected_when_one_command_is_bad():
    w, c = make()
    c.handle(":int:close 1")
    c.handle(":dem:rate 1,5;:mode:rate 1;:dem:rat 1,5")
    w.produce(500)
    assert c.mode[0] == "OFF" and w.table_state().rates[0] == 0.0


def test_mnemonic_forms_case_and_tree_traversal():
    w, c = make()
    for msg in (":INTERLOCK:CLOSE 1", "int:clos 2", ":I:C 3"):  # long, short without first colon, one letter
        c.handle(msg)
    assert c.servoed == [True, True, True]
    c.handle(":Mode:Position 1;Rate 2")  # stays in :Mode
    assert c.mode[:2] == ["POSITION", "RATE"]
    c.handle(":Dem:Pos 3,0.01;:Mode:Pos 3")  # ':' returns to the root
    assert c.mode[2] == "POSITION"
    c.handle(":mode 2,off;:MODE 1,R")  # the node command with enumerations by prefix
    assert c.mode[:2] == ["RATE", "OFF"]
    assert c.handle(":m? 1;:m? 2;:m? 3") == ["R;O;P"]
    assert c.status_byte() == 0


def test_reply_profiles():
    _, g = make("gpib")
    assert g.handle(":int:close 1") == [] and g.handle(":read:pos? 1") == ["0.0000"]
    _, t = make("tcp")
    assert t.handle(":int:close 1") == [""] and t.handle(":read:pos? 1;rate? 1") == ["0.0000;0.0000"]
    _, w = make(mode_reply="word", decimals=2)
    assert w.handle(":mode? 1;:read:rate? 1") == ["Off;0.00"]


def test_fixed_point_and_wrapped_positions_while_spinning():
    w, c = make(decimals=3)
    c.handle(":int:close 3;:dem:rate 3,100;:mode:rate 3")
    seen = []
    for _ in range(40):
        w.produce(100)
        (p,) = c.handle(":read:pos? 3")
        assert "e" not in p.lower() and len(p.split(".")[1]) == 3
        seen.append(float(p))
    assert all(-180 <= x < 180 for x in seen) and min(seen) < -90 and max(seen) > 90  # it went round


def test_read_acceleration_follows_the_profile():
    w, c = make()
    c.handle(":int:close ALL;:dem:rate 2,50;:mode:rate 2")
    w.produce(100)  # ramping at the 100 °/s² limit
    pos, rate, acc = map(float, c.handle(":read:pos? 2;rate? 2;acc? 2")[0].split(";"))
    assert acc == pytest.approx(100.0) and rate == pytest.approx(10.0, abs=0.01)
    w.produce(2000)
    assert float(c.handle(":R:A? 2")[0]) == 0.0


def test_position_mode_takes_the_shortest_path_on_a_continuous_axis():
    w, c = make()
    c.handle(":int:close ALL;:dem:pos 3,170;:mode:pos 3")
    w.produce(5000)
    c.handle(":dem:pos 3,-170")  # 20° forward across the wrap, not 340° back
    w.produce(3000)
    assert math.degrees(w.table_state().angles[2]) == pytest.approx(190.0, abs=1e-3)


def test_interlock_latches_on_a_fault_until_reset():
    w, c = make()
    c.handle(":int:close ALL;:dem:rate 1,20;:mode:rate 1")
    w.produce(500)
    w.inject_fault(FaultCode.STALL)
    assert int(c.handle(":Status:STB?")[0]) & 1  # SI
    assert c.handle(":interlock? 1") == ["Fault"] and c.servoed == [False, False, False]
    c.handle(":int:close 1")  # refused while latched
    assert c.errors and not c.servoed[0]
    c.handle(":Status:MSGCLR QERROR;:Interlock:Reset;:Interlock:Close 1")
    assert c.servoed[0] and c.status_byte() == 0 and w.table_state().fault_code == FaultCode.NONE
    assert c.handle(":int? 1") == ["Closed"]


def test_mode_needs_a_servoed_axis_and_off_stops():
    w, c = make()
    c.handle(":mode:rate 1")
    assert c.errors and c.mode[0] == "OFF"
    c.handle(":status:msgclr qerror;:int:close ALL;:dem:rate 1,50;:mode:rate 1;:dem:rate 2,-30;:mode:rate 2")
    w.produce(3000)
    s = w.table_state()
    assert s.rates[0] == pytest.approx(math.radians(50), rel=1e-4)
    assert s.rates[1] == pytest.approx(math.radians(-30), rel=1e-4)
    c.handle(":mode:off ALL")
    w.produce(3000)
    s = w.table_state()
    assert s.rates[0] == 0.0 and s.rates[1] == 0.0 and s.modes == (AxisMode.STOP,) * 3


def test_limits_per_mode_and_demands_beyond_them():
    w, c = make()
    assert c.handle(":lim:rate? r,1;:limit:rate? p,1;:L:A? P,1") == ["300.0000;270.0000;100.0000"]
    assert c.handle(":Limit:HighPosition? pos,2;:Limit:LowPosition? pos,2") == [
        f"{math.degrees(2.9):.4f};{-math.degrees(2.9):.4f}"
    ]
    assert c.handle(":limit:absolute? 3")[0].split(",")[3:5] == ["-180.0000", "180.0000"]
    c.handle(":int:close ALL;:dem:pos 2,170;:mode:pos 2")  # beyond the middle axis' ±166° limit
    assert c.errors and c.mode[1] == "OFF"


def test_stb_clears_on_read_but_status_stb_does_not():
    _, c = make()
    c.handle(":bogus")
    assert int(c.handle(":Status:STB?")[0]) & 0x20  # ESB
    assert int(c.handle(":Status:STB?")[0]) & 0x20
    c.handle("*STB?")
    assert not int(c.handle(":Status:STB?")[0]) & 0x20
    assert c.handle(":Status:MSG? QERROR,ALL")[0] and c.status_byte() == 0

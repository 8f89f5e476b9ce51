"""Exact messages of the ACL driver, written from the spec (docs/protocols/acutrol-acl.md), not from the
simulator: each test scripts (message the driver must send → reply the controller gives) with the one
transcript helper (tests/drivers/transcript.py, after PyMeasure's expected_protocol). Replies follow the
spec: GPIB answers only queries; TCP answers a plain command with an empty line; errors show in the status
byte and the error queue, never as text."""

from __future__ import annotations

import math

import numpy as np
import pytest

from drivers.acutrol import AclSettings, AclTurntable
from drivers.protocols import AxisLimits, AxisMode, FaultCode, LinkError, TableError, TableStatus
from tests.drivers.transcript import MessageTranscript

R = math.radians
LIMITS = (
    AxisLimits(rate_max=R(300), accel_max=R(100)),
    AxisLimits(rate_max=R(200), accel_max=R(100), position_min=R(-170), position_max=R(170)),
    AxisLimits(rate_max=R(400), accel_max=R(100)),
)
ENABLE = "*CLS;:Mode:Off 1;Off 2;Off 3;:Interlock:Close 1;Close 2;Close 3"
READ = ":Read:Position? 1;Position? 2;Position? 3;Rate? 1;Rate? 2;Rate? 3;:Mode? 1;:Mode? 2;:Mode? 3;:Status:STB?"
STB = ":Status:STB?"
INTL = ":Interlock? 1;:Interlock? 2;:Interlock? 3"
MSG = ":Status:MSG? QERROR;:Status:STB?"
NO_REPLY = None


def ack(profile: str) -> str | None:
    """What a plain command gets back: nothing on GPIB, an empty line on TCP."""
    return "" if profile == "tcp" else NO_REPLY


def table(script, profile="tcp", clock=None, **settings) -> tuple[AclTurntable, MessageTranscript]:
    """``clock``: the host clock at the driver's start, then at each reading (the driver reads it when it sends
    the reading's request and when the answer arrives: each reading's value is given to both)."""
    t = MessageTranscript(script)
    times = iter([clock[0], *(x for v in clock[1:] for x in (v, v))] if clock else [0.0] * 100)
    drv = AclTurntable(
        t,
        LIMITS,
        settings=AclSettings(reply_profile=profile, **settings),
        position_tolerance=R(2 / 3600),
        settle_time=0.2,
        rate_tolerance=R(0.01),
        clock=lambda: next(times),
    )
    return drv, t


@pytest.mark.parametrize("profile", ["gpib", "tcp"])
def test_enable_move_spin_stop(profile):
    a = ack(profile)
    drv, t = table(
        [
            (STB, "0"),
            (ENABLE, a),
            (STB, "0"),
            (READ, "0.0000;0.0000;0.0000;0.0000;0.0000;0.0000;O;O;O;0"),
            (":Demand:Position 1,10;Position 2,-20.5;Position 3,45;:Mode:Position 1;Position 2;Position 3", a),
            (STB, "0"),
            (":Demand:Rate 3,-15;:Mode:Rate 3", a),
            (STB, "0"),
            (":Mode:Off 1;Off 2;Off 3", a),
            (STB, "0"),
        ],
        profile,
    )
    drv.move_to([R(10), R(-20.5), R(45)])
    drv.spin(2, R(-15))
    drv.stop()
    drv.heartbeat()  # ACL has no heartbeat: nothing is sent
    t.done()


@pytest.mark.parametrize("profile", ["gpib", "tcp"])
def test_read_is_one_message_one_frame(profile):
    drv, t = table(
        [
            (READ + ";:Read:Variable? 7", "10.0001;44.1250;-0.0001;0.0000;0.5000;-15.0000;P;P;R;0;1234.5"),
            (INTL, "Closed;Closed;Closed"),  # a new session: the interlock state is read, not assumed
        ],
        profile,
        time_variable=7,
        time_scale_s=0.001,
    )
    s = drv.read_state()
    np.testing.assert_allclose(np.degrees(s.angles), [10.0001, 44.125, -0.0001], atol=1e-12)
    np.testing.assert_allclose(np.degrees(s.rates), [0.0, 0.5, -15.0], atol=1e-12)
    assert s.modes == (AxisMode.POSITION, AxisMode.POSITION, AxisMode.RATE)
    assert s.time == pytest.approx(1.2345) and s.fault_code == FaultCode.NONE
    assert not s.status & TableStatus.INTERLOCK_OPEN  # closed and servoed by an earlier session
    t.done()


def test_word_mode_replies_and_axis_numbers():
    msg = ":Read:Position? 3;Position? 1;Position? 2;Rate? 3;Rate? 1;Rate? 2;:Mode? 3;:Mode? 1;:Mode? 2;:Status:STB?"
    drv, t = table(
        [
            (msg, "1.0;2.0;3.0;0;0;0;Position;Rate;Off;0"),
            (":Interlock? 3;:Interlock? 1;:Interlock? 2", "Open;Open;Open"),
        ],
        mode_reply="word",
        axes=(3, 1, 2),
    )
    s = drv.read_state()
    assert s.modes == (AxisMode.POSITION, AxisMode.RATE, AxisMode.STOP) and s.status & TableStatus.INTERLOCK_OPEN
    t.done()
    drv, t = table([(READ, "0;0;0;0;0;0;Position;P;P;0")])  # letter expected, word received
    with pytest.raises(LinkError, match="mode_reply"):
        drv.read_state()


def test_positions_unwrapped_across_the_wrap():
    # inner axis spinning at +100 °/s, read every 0.2 s: 170° → −170° is +20°, not −340°
    drv, t = table(
        [
            (READ, "0;0;170.0000;0;0;100.0000;O;O;R;0"),
            (INTL, "Closed;Closed;Closed"),
            (READ, "0;0;-170.0000;0;0;100.0000;O;O;R;0"),
            (READ, "0;0;-150.0000;0;0;100.0000;O;O;R;0"),
        ],
        clock=[0.0, 0.0, 0.2, 0.4],
    )
    got = [math.degrees(drv.read_state().angles[2]) for _ in range(3)]
    np.testing.assert_allclose(got, [170.0, 190.0, 210.0], atol=1e-9)
    t.done()


def test_far_move_on_a_continuous_axis_goes_through_way_points():
    drv, t = table(
        [
            (STB, "0"),
            (ENABLE, ""),
            (STB, "0"),
            (READ, "0;0;0;0;0;0;O;O;O;0"),
            (":Demand:Position 1,0;Position 2,0;Position 3,110;:Mode:Position 1;Position 2;Position 3", ""),
            (STB, "0"),
            (READ, "0;0;60.0000;0;0;200.0000;P;P;P;0"),  # within 60° of the way-point: the next one (220° → −140°)
            (":Demand:Position 3,-140", ""),
            (STB, "0"),
            (READ, "0;0;170.0000;0;0;200.0000;P;P;P;0"),
            (":Demand:Position 3,-30", ""),  # 330°
            (STB, "0"),
            (READ, "0;0;-70.0000;0;0;200.0000;P;P;P;0"),  # 290° unwrapped
            (":Demand:Position 3,40", ""),  # 400° → 40°: the target itself, now less than 110° ahead
            (STB, "0"),
            (READ, "0;0;40.0000;0;0;0.0000;P;P;P;0"),
            (READ, "0;0;40.0000;0;0;0.0000;P;P;P;0"),
        ],
        clock=[0.0, 0.0, 0.5, 1.0, 1.5, 2.5, 2.7],
    )
    drv.move_to([0.0, 0.0, R(400)])
    drv.read_state()
    drv.read_state()
    assert math.degrees(drv.read_state().angles[2]) == pytest.approx(290.0)
    s = drv.read_state()
    assert math.degrees(s.angles[2]) == pytest.approx(400.0) and not s.status & TableStatus.IN_POSITION
    s = drv.read_state()  # inside the window for 0.2 s
    assert s.status & TableStatus.IN_POSITION and not s.status & TableStatus.MOVING
    t.done()


def test_settled_and_at_rate_decided_from_readings():
    drv, t = table(
        [
            (STB, "0"),
            (ENABLE, ""),
            (STB, "0"),
            (READ, "0;0;0;0;0;0;O;O;O;0"),
            (":Demand:Position 1,10;Position 2,0;Position 3,0;:Mode:Position 1;Position 2;Position 3", ""),
            (STB, "0"),
            (READ, "10.0010;0;0;0;0;0;P;P;P;0"),  # 3.6″ off: outside the 2″ window
            (READ, "10.0004;0;0;0;0;0;P;P;P;0"),  # inside from here (1.4″)
            (READ, "9.9998;0;0;0;0;0;P;P;P;0"),  # 0.1 s later: not yet 0.2 s
            (READ, "10.0000;0;0;0;0;0;P;P;P;0"),  # 0.2 s inside: settled
        ],
        clock=[0.0, 0.0, 1.0, 1.1, 1.2, 1.3],
    )
    drv.move_to([R(10), 0.0, 0.0])
    flags = [drv.read_state().status & TableStatus.IN_POSITION for _ in range(4)]
    assert [bool(f) for f in flags] == [False, False, False, True]
    t.done()


@pytest.mark.parametrize("profile", ["gpib", "tcp"])
def test_latched_interlock_fault_requires_an_acknowledgement(profile):
    a = ack(profile)
    drv, t = table(
        [
            (READ, "1.0;2.0;3.0;0;0;0;O;O;O;65"),  # *STB? bit 0 (SI) + bit 6 (MSS): the public client's "65"
            (INTL, "Fault;Fault;Fault"),
            # a motion command now is refused before anything is sent (no :Interlock:Reset behind the back)
            (STB, "65"),  # reset-fault: what the fault was, then :Interlock:Reset, then enable
            (INTL, "Fault;Closed;Closed"),
            (":Interlock:Reset", a),
            (STB, "0"),
            (ENABLE, a),
            (STB, "0"),
        ],
        profile,
    )
    s = drv.read_state()
    assert s.status & TableStatus.FAULT and s.fault_code == FaultCode.INTERLOCK
    assert "'Fault'" in drv.fault_report and "65" in drv.fault_report
    with pytest.raises(
        TableError, match=r"interlock fault latched \(status byte 65.*'Fault'.*nothing was sent.*reset-fault"
    ):
        drv.move_to([0.0, 0.0, 0.0])
    what = drv.clear_fault()
    assert "status byte 65" in what and "outer ':Interlock? 1' → 'Fault'" in what
    t.done()


@pytest.mark.parametrize("profile", ["gpib", "tcp"])
def test_a_fault_latched_in_a_new_session_is_not_reset_by_enable(profile):
    drv, t = table([(STB, "65"), (INTL, "Fault;Closed;Closed")], profile)
    with pytest.raises(TableError, match=r"status byte 65.*'Fault'.*reset-fault"):
        drv.spin(2, R(10))
    t.done()


@pytest.mark.parametrize("profile", ["gpib", "tcp"])
def test_refused_command_raises_with_the_error_queue_text(profile):
    a = ack(profile)
    drv, t = table(
        [
            (STB, "0"),
            (ENABLE, a),
            (STB, "0"),
            (":Demand:Rate 1,250;:Mode:Rate 1", a),
            (STB, "224"),  # EQ + MSS + ESB
            (MSG, '-222,"Data out of range";0'),
        ],
        profile,
    )
    with pytest.raises(TableError, match="Data out of range.*status byte 224"):
        drv.spin(0, R(250))
    t.done()


def test_a_queue_of_three_errors_is_reported_as_three():
    drv, t = table(
        [
            (STB, "0"),
            (ENABLE, ""),
            (STB, "0"),
            (":Demand:Rate 1,25;:Mode:Rate 1", ""),
            (STB, "128"),
            (MSG, '-222,"Data out of range";128'),
            (MSG, '-221,"Settings conflict";128'),
            (MSG, '-100,"Command error";0'),
            (":Mode:Off 1;Off 2;Off 3", ""),  # the stop that follows is not blamed for them
            (STB, "0"),
        ]
    )
    with pytest.raises(TableError) as e:
        drv.spin(0, R(25))
    msg = str(e.value)
    assert msg.startswith("ACUTROL refused spin") and "3 errors: [1] -222" in msg
    assert '[2] -221,"Settings conflict"' in msg and '[3] -100,"Command error"' in msg
    drv.stop()
    t.done()


def test_errors_left_from_before_the_session_are_not_blamed():
    drv, t = table(
        [
            (READ, "0;0;0;0;0;0;O;O;O;128"),
            (MSG, '-113,"Undefined header";0'),
            (INTL, "Open;Open;Open"),
            (STB, "0"),
            (ENABLE, ""),
            (STB, "0"),
        ]
    )
    s = drv.read_state()
    assert s.status & TableStatus.INTERLOCK_OPEN and drv.stale_errors == ['-113,"Undefined header"']
    drv.enable()
    t.done()


def test_refused_query_dead_link_and_wrong_framing_are_told_apart():
    drv, t = table([(READ, NO_REPLY), (STB, "128"), (MSG, '-113,"Undefined header";0')], "gpib")
    with pytest.raises(TableError, match=r"ACUTROL refused ':Read:Position\? 1.*-113,\"Undefined header\""):
        drv.read_state()
    t.done()
    drv, t = table([(READ, NO_REPLY), (STB, NO_REPLY)], "gpib")
    with pytest.raises(LinkError, match="nor to a status query: the link is dead"):
        drv.read_state()
    t.done()
    drv, t = table([(READ, NO_REPLY), (STB, "0")], "gpib")
    with pytest.raises(LinkError, match="answers status queries .* but did not answer the query.*reply_profile"):
        drv.read_state()
    t.done()


def test_a_reply_profile_mismatch_names_the_bench_file():
    drv, t = table(
        [(STB, "0"), (ENABLE, NO_REPLY), (STB, "0")],  # a GPIB-like controller behind a tcp setting
        "tcp",
        source="bench.yaml:17 turntable.acl.reply_profile",
    )
    with pytest.raises(LinkError, match=r"did not acknowledge.*now 'tcp'; set at bench.yaml:17 turntable.acl"):
        drv.enable()
    t.done()


def test_demands_checked_before_sending():
    drv, t = table([])
    with pytest.raises(TableError, match="nothing was sent"):
        drv.move_to([0.0, R(175), 0.0])  # middle limited to ±170°
    with pytest.raises(TableError, match="nothing was sent"):
        drv.spin(2, R(401))
    assert t.sent == []


def test_a_short_reading_is_a_link_error():
    drv, t = table([(READ, "1.0;2.0")], "gpib")
    with pytest.raises(LinkError, match="10 fields.*turntable.acl"):
        drv.read_state()


def test_tcp_profile_acknowledgement_must_be_empty():
    drv, t = table([(STB, "0"), (ENABLE, "OK")], "tcp")
    with pytest.raises(LinkError, match="reply_profile"):
        drv.enable()


@pytest.mark.parametrize("profile", ["gpib", "tcp"])
def test_close_stops_and_opens_interlocks_when_asked(profile):
    a = ack(profile)
    drv, t = table(
        [
            (STB, "0"),
            (ENABLE, a),
            (STB, "0"),
            (":Demand:Rate 2,5;:Mode:Rate 2", a),
            (STB, "0"),
            (":Mode:Off 1;Off 2;Off 3", a),
            (STB, "0"),
            (":Interlock:Open 1;Open 2;Open 3", a),
        ],
        profile,
        open_interlocks_at_end=True,
    )
    drv.spin(1, R(5))
    drv.close()
    t.done()
    with pytest.raises(LinkError, match="closed"):
        drv.read_state()


def test_leave_running_sends_nothing_on_close():
    drv, t = table([(STB, "0"), (ENABLE, ""), (STB, "0"), (":Demand:Rate 1,-2.25;:Mode:Rate 1", ""), (STB, "0")])
    drv.spin(0, R(-2.25))
    drv.leave_running()
    drv.close()
    t.done()


def test_controller_working_limits_per_mode():
    q = ":Limit:Rate? P,{a};Rate? R,{a};Acceleration? P,{a};Acceleration? R,{a};HighPosition? P,{a};LowPosition? P,{a}"
    drv, t = table([(q.format(a=a), f"{100 * a}.0;{110 * a}.0;50.0;60.0;170.0;-170.0") for a in (1, 2, 3)], "gpib")
    lim = drv.controller_limits()
    assert lim[2] == {
        "rate_position": 300.0,
        "rate_rate": 330.0,
        "accel_position": 50.0,
        "accel_rate": 60.0,
        "high": 170.0,
        "low": -170.0,
    }
    t.done()

"""Does another connection (opened, or a cycle request on it) close the first? The pure verdict and titles."""

from __future__ import annotations

from conformance.diagnose import conn_titles
from conformance.diagnose.conn_peers import NONE, OFF, ON, Steps, judge
from conformance.diagnose.hypotheses import Status


def test_a_second_connection_closing_the_first_is_confirmed() -> None:
    action, (status, why) = judge(Steps(((NONE, False, 0.01),)))
    assert action == NONE and status is Status.CONFIRMED and "opened" in why


def test_cycleoff_on_another_connection_closing_it_is_confirmed() -> None:
    action, (status, _) = judge(Steps(((NONE, True, 0.01), (ON, True, 0.02), (OFF, False, 0.01))))
    assert action == OFF and status is Status.CONFIRMED


def test_a_close_after_a_slow_step_may_be_idleness() -> None:
    action, (status, why) = judge(Steps(((NONE, True, 0.01), (ON, False, 1.6))))
    assert action is None and status is Status.CONSISTENT and "idle 1.6 s" in why


def test_kept_answering_rules_it_out_and_silence_leaves_it_untested() -> None:
    assert judge(Steps(((NONE, True, 0.0), (ON, True, 0.0), (OFF, True, 0.0))))[1][0] is Status.RULED_OUT
    assert judge(Steps(((NONE, None, 0.0),)))[1][0] is Status.UNTESTED
    assert judge(Steps(()))[1][0] is Status.UNTESTED


def test_titles_name_what_closed_it() -> None:
    assert "another one opens" in conn_titles.peer_close(NONE)
    assert "CycleOff (02)" in conn_titles.peer_close(OFF)


def test_open_limit_is_confirmed_only_when_a_fresh_connection_is_served_after_they_close() -> None:
    from conformance.diagnose.conn_limit import KIND, Held
    from conformance.diagnose.conn_limit import judge as limit

    assert limit(Held(8, True, 9)) == (KIND, limit(Held(8, True, 9))[1])
    assert limit(Held(8, True, 9))[1][0] is Status.CONFIRMED
    assert limit(Held(8, False, 9))[0] == "" and limit(Held(8, False, 9))[1][0] is Status.CONSISTENT
    assert limit(Held(None, None, 48))[1][0] is Status.RULED_OUT
    assert limit(Held(1, True, 2))[1][0] is Status.UNTESTED
    assert "once 8 connections are held open" in conn_titles.open_limit(8)


def test_a_close_of_the_command_connection_when_the_stream_closes_is_named_so() -> None:
    from conformance.diagnose.conn_peers import STREAM_CLOSED
    from conformance.diagnose.conn_titles import peer_close

    after = ((NONE, True, 0.0), (ON, True, 0.0), (OFF, True, 0.0), (STREAM_CLOSED, False, 0.25))
    action, (status, why) = judge(Steps(after, control=True))  # A survived as long with B left open
    assert action == STREAM_CLOSED and status is Status.CONFIRMED and "close of connection B" in why
    for control in (False, None):  # A closed with B open too, or not tried: idle time may explain it
        action, (status, _) = judge(Steps(after, control=control))
        assert action is None and status is Status.CONSISTENT
    title = peer_close(STREAM_CLOSED)
    assert "stream" in title and "closes" in title and "command connection" in title

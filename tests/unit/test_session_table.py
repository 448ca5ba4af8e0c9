"""conformance/protocol/session_table.py: the cycle's transitions and the canonical orders, once; the fuzz
session machine, analyze, the observed sessions, the reference box and the robot simulator read them."""

from __future__ import annotations

import pytest

from conformance.protocol import Action, ErrorCode, ResultCode
from conformance.protocol.answers import ALLOWED_CODES
from conformance.protocol.session_table import (
    E4,
    S1,
    Cycle,
    box_cycle_after,
    commands,
    cycle_after,
    ends_session,
    milestones,
)

ON, OFF = Action.CYCLE_ON, Action.CYCLE_OFF


@pytest.mark.parametrize("before", list(Cycle))
def test_what_each_cycle_answer_does_to_the_state(before: Cycle) -> None:
    assert cycle_after(before, ON, ErrorCode.OK) is Cycle.ON  # S2 (S3: on already, stays on)
    assert cycle_after(before, ON, ErrorCode.NOT_READY) is before  # S2: not ready, no cycle started
    assert cycle_after(before, OFF, ErrorCode.OK) is Cycle.IDLE
    # A3: 0002, the detection not closed properly: PROTOCOL.md does not say whether the cycle is still on
    assert cycle_after(before, OFF, ErrorCode.CYCLE_OFF_FAILED) is Cycle.UNKNOWN
    assert cycle_after(before, ON, ErrorCode.POSE_ERROR) is Cycle.UNKNOWN  # a code the table does not list
    for action in (Action.NONE, Action.POSE, Action.REGISTER_POSE, Action.TOLERANCE, Action.PROG_IDX,
                   Action.VISION_RESULT):
        assert cycle_after(before, action, ErrorCode.OK) is before  # S3: in or out of a cycle
        assert cycle_after(before, action, ErrorCode.POSE_ERROR) is before


def test_the_box_keeps_its_own_state_where_a_tester_cannot_know_it() -> None:
    assert box_cycle_after(Cycle.ON, OFF, ErrorCode.CYCLE_OFF_FAILED) is Cycle.ON
    assert box_cycle_after(Cycle.IDLE, ON, ErrorCode.NOT_READY) is Cycle.IDLE
    assert box_cycle_after(Cycle.IDLE, ON, ErrorCode.OK) is Cycle.ON


def test_a_state_the_table_reaches_is_one_an_allowed_answer_leads_to() -> None:
    """Every answer the table turns into a known state is one a conforming box may give in some state."""
    for before in (Cycle.IDLE, Cycle.ON):
        for action, code in ((ON, ErrorCode.OK), (OFF, ErrorCode.OK), (ON, ErrorCode.NOT_READY)):
            allowed = ALLOWED_CODES[(before, action)]
            assert allowed is None or code in allowed


def test_the_canonical_orders() -> None:
    names = [step.name for step in S1]
    assert names == ["connect", "send_pos_on", "cycle_on", "trajectory", "cycle_off", "send_pos_off", "disconnect"]
    assert [step.name for step in E4 if step.name not in ("prog_idx", "result_wait", "vision_result")] == names
    assert milestones(S1) == ("command connect", "stream connect", "CycleOn", "CycleOff", "stream close",
                              "command disconnect")
    assert commands(E4) == (Action.PROG_IDX, ON, OFF, Action.VISION_RESULT) and commands(S1) == (ON, OFF)


def test_the_robot_simulator_and_the_observer_play_the_same_order() -> None:
    from conformance.endpoints.robot.robot_steps import E4_STEPS, S1_STEPS, STEP_TABLE
    from conformance.observed import session as observed

    for order, played, observed_steps in ((S1, S1_STEPS, observed.S1_STEPS), (E4, E4_STEPS, observed.E4_STEPS)):
        assert played == tuple(step.name for step in order)
        assert observed_steps == milestones(order)
        assert all(STEP_TABLE[step.name].io is step.io and STEP_TABLE[step.name].action is step.action
                   for step in order)


def test_the_answers_after_which_a_robot_may_stop() -> None:
    assert ends_session(ON, ErrorCode.NOT_READY) and ends_session(Action.POSE, ErrorCode.POSE_ERROR)
    assert ends_session(Action.PROG_IDX, ErrorCode.OK, ResultCode.CONFLICT)
    assert not ends_session(Action.PROG_IDX, ErrorCode.OK, 7) and not ends_session(OFF, ErrorCode.OK)
    assert not ends_session(Action.NONE, None)


def test_analyze_follows_the_table_after_a_failed_cycle_off() -> None:
    from types import SimpleNamespace

    from conformance.analyze.judging import Cycles

    cycles, conn = Cycles(), SimpleNamespace(cycle=Cycle.IDLE)
    cycles.answered("box", conn, ON, ErrorCode.OK)
    assert cycles.state("box", conn.cycle) is Cycle.ON
    cycles.answered("box", conn, OFF, ErrorCode.CYCLE_OFF_FAILED)
    assert cycles.state("box", conn.cycle) is Cycle.UNKNOWN

"""What one exchange shows, filed under the observed cases (conformance/analyze/judging.py):
the protocol's facts about answers (conformance/protocol/answers.py) decide, this module
files each finding where a reader looks for it, and knows the box's cycle state only
from what the capture showed."""

from __future__ import annotations

import pytest

from conformance.analyze.analysis_context import AnalyzeConfig, Context
from conformance.analyze.exchanges import ConnJudge
from conformance.analyze.judging import Cycles, count_frames, expect, judge_pair
from conformance.model.verdicts import Verdict
from conformance.protocol import (
    Action,
    Header,
    ProtocolError,
    StartWordError,
    answer,
    decode_datagram,
    encode,
    encode_raw,
    encode_udp,
    parse_frame,
    pose_blocks,
    request,
    tolerance_blocks,
    value_blocks,
)
from conformance.protocol.answers import Cycle, Rule


def judge(transport: str = "tcp") -> ConnJudge:
    return ConnJudge(Context(AnalyzeConfig()), "conn 1", transport, box=("10.0.0.1", 9004))


def pair(j: ConnJudge, req, ans, transport: str = "tcp") -> None:
    """File the box's answer ``ans`` (a Frame) to the robot's request ``req`` (a Frame or bytes)."""
    if isinstance(req, bytes):
        try:
            r_event = decode_datagram(req, j.ctx.judged) if transport == "udp" else parse_frame(req, j.ctx.judged)
        except ProtocolError as exc:
            r_event = exc
    else:
        r_event = req
    action = r_event.action if hasattr(r_event, "action") else (r_event.header.action if r_event.header else None)
    judge_pair(j, None, action, r_event, ans, ans.error_code, (1, 2), b"", encode(ans), 1.0)


def worst(j: ConnJudge, clause: str):
    t = j.findings.tallies.get((clause, "box"))
    return t.worst() if t else None


def test_what_the_box_may_do_with_each_event():
    ctx = Context(AnalyzeConfig())
    assert expect(request(Action.POSE, pose_blocks([(1, 2, 3, 4, 5, 6)])), ctx, "tcp").rule is Rule.ANSWER
    assert expect(StartWordError("garbage"), ctx, "tcp").rule is Rule.NOT_REQUEST
    good = encode_udp(request(Action.NONE))
    with pytest.raises(ProtocolError) as info:
        decode_datagram(good[:-1] + bytes([good[-1] ^ 0xFF]))
    assert expect(info.value, ctx, "udp").rule is Rule.DROP


def test_the_cycle_state_is_known_only_when_the_box_and_the_connection_agree():
    cycles = Cycles()
    j = judge()
    box = ("10.0.0.1", 9004)
    assert cycles.state(box, Cycle.IDLE) is Cycle.UNKNOWN  # the capture began with the box in some state
    cycles.answered(box, j, Action.CYCLE_OFF, 0)
    assert cycles.state(box, j.cycle) is Cycle.IDLE
    cycles.answered(box, j, Action.CYCLE_ON, 0)
    assert cycles.state(box, j.cycle) is Cycle.ON and cycles.state(box, Cycle.IDLE) is Cycle.UNKNOWN
    cycles.answered(box, j, Action.CYCLE_OFF, 2)
    assert cycles.state(box, j.cycle) is Cycle.UNKNOWN


def test_a_wrong_code_is_filed_by_the_requests_action():
    j = judge()
    pair(j, request(Action.REGISTER_POSE, pose_blocks([(1, 2, 3, 4, 5, 6)])), answer(Action.REGISTER_POSE, 0x1001))
    pair(j, request(Action.TOLERANCE, tolerance_blocks([0.5])), answer(Action.TOLERANCE, 0x1002))
    assert worst(j, "S3") is Verdict.FAIL and worst(j, "A3") is Verdict.FAIL
    assert j.refusals  # the robot may stop its session after either


def test_cycle_on_and_off_against_the_state_the_capture_showed():
    j = judge()
    pair(j, request(Action.CYCLE_ON), answer(Action.CYCLE_ON, 3))  # state unknown: a MAY
    assert worst(j, "S2") is Verdict.INFORMATIONAL
    j.ctx.cycles.answered(j.box, j, Action.CYCLE_OFF, 0)  # now the capture has shown the box idle
    pair(j, request(Action.CYCLE_ON), answer(Action.CYCLE_ON, 3))
    assert worst(j, "S2") is Verdict.FAIL
    pair(j, request(Action.CYCLE_OFF), answer(Action.CYCLE_OFF, 2))  # box was idle: CycleOff without CycleOn
    assert j.findings.tallies[("A3", "box")].counts.get(Verdict.FAIL) is None


def test_0000_to_malformed_input_is_r1_and_to_a_bad_datagram_r7():
    j = judge()
    bad_index = encode_raw(Header(action=Action.POSE, block_type=1, block_count=1, block_length=25), bytes([5]) + bytes(24))
    pair(j, bad_index, answer(Action.POSE, 0))
    pair(j, bad_index, answer(Action.POSE, 0x1001))
    assert j.findings.tallies[("R1", "box")].counts == {Verdict.FAIL: 1} and j.findings.tallies[("R1", "box")].checked
    u = judge("udp")
    good = encode_udp(request(Action.NONE))
    pair(u, good[:-1] + bytes([good[-1] ^ 0xFF]), answer(Action.NONE, 0), "udp")
    assert worst(u, "R7") is Verdict.FAIL


def test_prog_idx_409_is_reported_and_cuts_the_session():
    j = judge()
    pair(j, request(Action.PROG_IDX, value_blocks([4])), answer(Action.PROG_IDX, blocks=value_blocks([409])))
    assert worst(j, "E2") is Verdict.INFORMATIONAL and "409" in j.refusals[0][1]


def test_frames_are_counted_per_clause_and_side():
    j = judge()
    j.poses, j.box_poses = 7, 7
    j.robot_counts = {Action.TOLERANCE: 2, Action.PROG_IDX: 1}
    j.box_counts = {Action.TOLERANCE: 2, Action.PROG_IDX: 1}
    count_frames(j)
    t = j.findings.tallies
    assert t[("F1", "robot")].checked == 10 and t[("F6", "box")].checked == 10
    assert t[("B1", "robot")].checked == 7 and t[("B3", "robot")].checked == 10 and t[("E1", "box")].checked == 1
    assert ("F7", "robot") not in t


"""One connection's requests and answers (conformance/analyze/exchanges.py), fed event by
event: pairing in order (A1), the answer's content (A2, A3, A4, S2, S3, E2, E3), its
latency (T1), 0000 to malformed input (R1) only when no legal pairing explains it, and
INCONCLUSIVE (never FAIL) where a gap or a mid-connection start hides the pairing."""

from __future__ import annotations

import pytest

from conformance.analyze.analysis_context import AnalyzeConfig, Context
from conformance.analyze.exchanges import ConnJudge
from conformance.model.verdicts import Verdict
from conformance.protocol import (
    Action,
    Header,
    Profile,
    ProtocolError,
    TransferType,
    answer,
    encode,
    encode_raw,
    parse_frame,
    pose_blocks,
    request,
    value_blocks,
)
from conformance.protocol.answers import Cycle

POSE = request(Action.POSE, pose_blocks([(800.0, 1.0, 2.0, 3.0, 4.0, 5.0)]))
BAD_POSE = encode_raw(Header(action=Action.POSE, block_type=1, block_count=1, block_length=25), bytes([3]) + bytes(24))


class Conn:
    def __init__(self, midstart: bool = False, profile: Profile | None = None) -> None:
        self.ctx = Context(AnalyzeConfig(profile=profile or Profile(time_out_ms=100)))
        self.judge = ConnJudge(self.ctx, "conn 1 (robot → box)", midstart=midstart)
        self.frame, self.t = 0, 0.0

    def _event(self, data: bytes, expect: TransferType):
        try:
            return parse_frame(data, self.ctx.judged, expect=expect)
        except ProtocolError as exc:
            return exc

    def robot(self, frame_or_bytes, dt: float = 0.001) -> None:
        data = frame_or_bytes if isinstance(frame_or_bytes, bytes) else encode(frame_or_bytes)
        self.frame, self.t = self.frame + 1, self.t + dt
        self.judge.request(self._event(data, TransferType.ROBOT_TO_BOX), data, 0, self.frame, self.frame, self.t)

    def box(self, frame_or_bytes, dt: float = 0.001) -> None:
        data = frame_or_bytes if isinstance(frame_or_bytes, bytes) else encode(frame_or_bytes)
        self.frame, self.t = self.frame + 1, self.t + dt
        self.judge.answer(self._event(data, TransferType.BOX_TO_ROBOT), data, 0, self.frame, self.frame, self.t)

    def end(self, how: str = "robot") -> dict[tuple[str, str], object]:
        self.judge.finish(how, self.t + 0.001, self.t + 0.001 if how in ("box", "robot") else None, self.frame + 1)
        return self.ctx.findings.tallies

    def worst(self, clause: str, side: str = "box"):
        t = self.ctx.findings.tallies.get((clause, side))
        return t.worst() if t else None

    def first(self, clause: str, verdict: Verdict, side: str = "box") -> str:
        return self.ctx.findings.tallies[(clause, side)].kept[verdict][0].line()


def test_requests_answered_in_order_pass():
    c = Conn()
    for action in (Action.NONE, Action.CYCLE_ON, Action.CYCLE_OFF):
        c.robot(request(action))
        c.box(answer(action))
    for _ in range(5):
        c.robot(POSE)
    for _ in range(5):
        c.box(answer(Action.POSE))
    c.end()
    for clause in ("A1", "A2", "A3", "A4", "S2", "S3", "T1"):
        assert c.worst(clause) is None and c.ctx.findings.tallies[(clause, "box")].checked, clause
    assert c.ctx.findings.tallies[("A1", "box")].checked == 8


def test_an_extra_answer_fails_a1_and_names_its_frame():
    c = Conn()
    c.robot(request(Action.NONE))
    c.box(answer(Action.NONE))
    c.box(answer(Action.NONE))
    c.end()
    assert c.worst("A1") is Verdict.FAIL and c.first("A1", Verdict.FAIL).startswith("frame 3:")


def test_an_answer_that_does_not_echo_fails_a2():
    c = Conn()
    c.robot(request(Action.CYCLE_ON))
    c.box(answer(Action.CYCLE_OFF))
    c.end()
    assert c.worst("A2") is Verdict.FAIL and "carries action CYCLE_OFF" in c.first("A2", Verdict.FAIL)


def test_a_late_answer_fails_t1_and_an_unanswered_request_fails_a1_when_the_box_closes():
    c = Conn()
    c.robot(request(Action.NONE))
    c.box(answer(Action.NONE), dt=0.5)  # time_out 100 ms
    c.robot(request(Action.CYCLE_ON))
    c.end("box")
    assert c.worst("T1") is Verdict.FAIL and "after 500.0 ms" in c.first("T1", Verdict.FAIL)
    assert c.worst("A1") is Verdict.FAIL and "never answered" in c.first("A1", Verdict.FAIL)


def test_an_unanswered_request_at_the_capture_end_is_inconclusive_within_time_out():
    c = Conn()
    c.robot(request(Action.NONE))
    c.end("capture")
    assert c.worst("A1") is Verdict.INCONCLUSIVE and c.worst("T1") is None


@pytest.mark.parametrize("code, idle, verdict", [
    (0x0001, True, Verdict.INFORMATIONAL), (0x0003, True, Verdict.FAIL),
    (0x0003, False, Verdict.INFORMATIONAL),  # the box's cycle state unknown: CycleOn twice MAY be an error
])
def test_cycle_on_codes(code, idle, verdict):
    c = Conn()
    if idle:
        c.ctx.cycles.boxes[None] = Cycle.IDLE  # the capture showed this box's last cycle end
    c.robot(request(Action.CYCLE_ON))
    c.box(answer(Action.CYCLE_ON, code))
    c.end()
    assert c.worst("S2") is verdict
    assert c.judge.refusals  # the robot may stop here: the session is cut


def test_a_well_formed_pose_answered_with_an_error_fails_s3():
    c = Conn()
    c.robot(POSE)
    c.box(answer(Action.POSE, 0x1001))
    c.end()
    assert c.worst("S3") is Verdict.FAIL


def test_a_malformed_pose_answered_0000_fails_r1_answered_1001_passes():
    c = Conn()
    c.robot(BAD_POSE)
    c.box(answer(Action.POSE, 0))
    c.robot(BAD_POSE)
    c.box(answer(Action.POSE, 0x1001))
    c.end()
    assert c.worst("R1") is Verdict.FAIL and "MUST NOT be answered 0000" in c.first("R1", Verdict.FAIL)
    assert c.ctx.findings.tallies[("R1", "box")].counts == {Verdict.FAIL: 1}
    assert c.worst("B3", "robot") is Verdict.FAIL  # and the robot is blamed for sending it


def test_silence_on_a_malformed_pose_then_0000_to_a_valid_one_is_legal():
    c = Conn()
    c.robot(BAD_POSE)
    c.robot(POSE)
    c.box(answer(Action.POSE, 0))  # the valid pose's answer: the box dropped the malformed one
    c.end()
    assert c.worst("R1") is None and c.worst("A1") is None
    assert c.worst("A3") is Verdict.NON_STRICT  # it SHOULD have answered 1001


def test_when_no_legal_pairing_explains_a_0000_it_is_r1():
    c = Conn()
    c.robot(BAD_POSE)
    c.robot(POSE)
    c.box(answer(Action.POSE, 0))
    c.box(answer(Action.POSE, 0))  # two 0000s for one valid pose: the malformed one got 0000
    c.end()
    assert c.worst("R1") is Verdict.FAIL and c.worst("A1") is None


def test_garbage_from_the_robot_may_go_unanswered_and_r6_is_judged_after_it():
    c = Conn()
    c.robot(b"hello there!")
    c.robot(request(Action.NONE))
    c.box(answer(Action.NONE))
    c.end()
    assert c.worst("F1", "robot") is Verdict.FAIL
    assert c.worst("R1") is None and c.worst("R6") is None and c.ctx.findings.tallies[("R6", "box")].checked == 1
    c2 = Conn()
    c2.robot(b"hello there!")
    c2.robot(request(Action.NONE))
    c2.end("capture")
    assert c2.worst("R6") is Verdict.NON_STRICT


def test_prog_idx_and_result():
    c = Conn()
    c.robot(request(Action.PROG_IDX, value_blocks([7])))
    c.box(answer(Action.PROG_IDX, blocks=value_blocks([8])))
    c.robot(request(Action.VISION_RESULT))
    c.box(answer(Action.VISION_RESULT, blocks=value_blocks([3])))
    c.robot(request(Action.PROG_IDX, value_blocks([7])))
    c.box(answer(Action.PROG_IDX, blocks=value_blocks([409])))
    c.end()
    t = c.ctx.findings.tallies
    assert t[("E2", "box")].counts == {Verdict.FAIL: 1, Verdict.INFORMATIONAL: 1}
    assert c.worst("E3") is Verdict.FAIL and "value=3" in c.first("E3", Verdict.FAIL)


def test_a_gap_makes_pairing_inconclusive_never_fail():
    c = Conn()
    c.robot(POSE)
    c.judge.gap("robot", 1, 3)
    c.box(answer(Action.POSE))
    c.box(answer(Action.POSE))  # would be an extra answer, but a request may be in the gap
    c.end()
    assert c.worst("A1") is Verdict.INCONCLUSIVE and c.worst("T1") is Verdict.INCONCLUSIVE
    assert "between frame 1 and frame 3" in c.first("A1", Verdict.INCONCLUSIVE)


def test_a_connection_seen_mid_way_ignores_answers_to_earlier_requests():
    c = Conn(midstart=True)
    c.box(answer(Action.POSE))  # its request went before the capture began
    c.robot(POSE)
    c.box(answer(Action.POSE))
    c.end()
    assert c.worst("A1") is None and c.judge.paired == 1


def test_the_byte_order_of_the_robots_values():
    c = Conn()
    c.robot(encode(POSE, Profile(float_byte_order="little")))
    c.box(answer(Action.POSE))
    c.end()
    assert c.worst("F4", "robot") is Verdict.FAIL and c.worst("F4") is None


def test_a_box_far_behind_stops_pairing_instead_of_holding_every_request(monkeypatch):
    import conformance.analyze.exchanges as ex

    monkeypatch.setattr(ex, "MAX_OUTSTANDING", 50)
    c = Conn()
    for _ in range(60):
        c.robot(POSE, dt=0.02)  # never answered; 20 ms apart, time_out 100 ms
    assert len(c.judge.queue) <= 50 and c.judge.desync is not None
    c.end("capture")
    assert c.worst("A1") is Verdict.FAIL and c.worst("T1") is Verdict.FAIL
    assert c.ctx.findings.tallies[("A1", "box")].counts[Verdict.INCONCLUSIVE] == 1

"""The fuzz oracle (conformance/fuzz/oracle.py): expectations from the bytes, and judging outcomes."""

from __future__ import annotations

import pytest

from conformance.fuzz.oracle import Rule, expectations, judge
from conformance.harness.client import Answer, Closed, Malformed, Outcome, Silence
from conformance.model.verdicts import Verdict
from conformance.protocol import (
    Action,
    Header,
    Profile,
    ProtocolError,
    TransferType,
    Transport,
    answer,
    encode,
    encode_raw,
    encode_udp,
    parse_frame,
    pose_blocks,
    request,
    tolerance_blocks,
    value_blocks,
)

P = Profile()
NONE = encode(request(Action.NONE))
POSE = encode(request(Action.POSE, pose_blocks([(1.0, 2.0, 3.0, 4.0, 5.0, 6.0)])))
BAD_INDEX = encode(request(Action.POSE, pose_blocks([(0.0,) * 6], first_index=1)))
BAD_TOLERANCE = encode_raw(Header(action=Action.TOLERANCE, block_type=2, block_count=0, block_length=5))
NAN_POSE = encode(request(Action.POSE, pose_blocks([(float("nan"), 0, 0, 0, 0, 0)])))
GARBAGE = b"hello"


def ans(action: int, error: int = 0, blocks: tuple = ()) -> Answer:
    frame = answer(Action(action), error, blocks)
    return Answer(frame, 0.001, encode(frame))


def malformed(data: bytes) -> Malformed:
    try:
        parse_frame(data, P, Transport.TCP, TransferType.BOX_TO_ROBOT)
    except ProtocolError as exc:
        return Malformed(exc, 0.001)
    raise AssertionError("not malformed")


PROBE = ans(Action.NONE)


def verdict(data: bytes, outcomes: list[Outcome], end: Outcome | None = PROBE, **kw: object) -> tuple[Verdict, list[str]]:
    _, exp = expectations(data, P, **kw)  # type: ignore[arg-type]
    j = judge(exp, outcomes, end, P, None if kw.get("eof") else Action.NONE)
    return j.verdict, [f.clause for f in j.findings]


# -- expectations -------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("data", "kw", "rule", "clause", "named"),
    [
        (NONE, {}, Rule.ANSWER, "", None),
        (BAD_INDEX, {}, Rule.REJECT, "B3", 0x1001),
        (BAD_TOLERANCE, {}, Rule.REJECT, "B5", 0x1002),
        (encode_raw(Header(action=Action.CYCLE_ON, block_count=1)), {}, Rule.REJECT, "B5", None),
        (GARBAGE, {}, Rule.NOT_REQUEST, "F1", None),
        (encode_raw(Header(version=2)), {}, Rule.NOT_REQUEST, "F2", None),
        (encode_raw(Header(transfer_type=0x10)), {}, Rule.NOT_REQUEST, "F3", None),
        (encode_raw(Header(action=0x99)), {}, Rule.NOT_REQUEST, "A5", None),
        (encode(request(Action.VISION_RESULT)), {"extension": False}, Rule.NOT_REQUEST, "A5", None),
        (NAN_POSE, {}, Rule.REJECT_SHOULD, "B4", 0x1001),
        (encode(request(Action.POSE, pose_blocks([(0.0,) * 6])), P, Transport.UDP), {}, Rule.ANSWER_SHOULD, "F6", None),
        (NONE[:-2] + b"\x12\x34", {}, Rule.ANY, "F6", None),
        (encode(request(Action.NONE, error_code=7)), {}, Rule.ANY, "", None),
        (POSE[:20], {"eof": True}, Rule.REJECT, "F5", None),
        (NONE[:5], {"eof": True}, Rule.NOT_REQUEST, "F5", None),
        (encode_udp(request(Action.NONE))[:-1] + b"\x00", {"transport": Transport.UDP}, Rule.DROP, "F7", None),
    ],
    ids=["valid", "b3", "tolerance-shape", "cycle-on-shape", "garbage", "version", "direction", "unknown", "27-no-e",
         "nan", "tcp-crc", "tcp-check", "request-error", "truncated-eof", "cut-header-eof", "udp-crc"],
)
def test_expectations(data: bytes, kw: dict, rule: Rule, clause: str, named: int | None) -> None:
    _, exp = expectations(data, P, **kw)
    assert (exp[0].rule, exp[0].clause, exp[0].named_error) == (rule, clause, named)


def test_a_lenient_profile_leaves_nan_open_and_cycles_accept_any_code() -> None:
    _, exp = expectations(NAN_POSE, Profile(strict=False))
    assert exp[0].rule is Rule.ANY
    _, (on,) = expectations(encode(request(Action.CYCLE_ON)), P)
    assert on.rule is Rule.ANSWER and on.ok_errors is None
    _, (idx,) = expectations(encode(request(Action.PROG_IDX, value_blocks([7]))), P)
    assert idx.values == frozenset({7, 409})


def test_an_open_frame_is_completed_with_filler_so_the_probe_starts_a_frame() -> None:
    cut = POSE[:20]
    filler, exp = expectations(cut, P)
    assert filler == bytes(len(POSE) - 20) and len(exp) == 1
    filler, exp = expectations(b"\xfe\xfe\x00\x01\x01", P)  # half a header
    assert len(filler) >= 7 and exp


def test_events_after_an_error_are_marked() -> None:
    _, exp = expectations(GARBAGE + NONE, P)
    assert [e.rule for e in exp] == [Rule.NOT_REQUEST, Rule.ANSWER] and exp[1].after_error


# -- judging ---------------------------------------------------------------------------------------------


def test_a_parse_error_answered_with_its_error_passes_and_0000_fails() -> None:
    assert verdict(BAD_INDEX, [ans(Action.POSE, 0x1001)]) == (Verdict.PASS, [])
    assert verdict(BAD_INDEX, [ans(Action.POSE, 0)]) == (Verdict.FAIL, ["B3"])
    assert verdict(BAD_INDEX, [ans(Action.POSE, 0x0001)]) == (Verdict.NON_STRICT, ["A3"])
    assert verdict(BAD_INDEX, []) == (Verdict.NON_STRICT, ["A3"])  # silent: the SHOULD of A3
    assert verdict(BAD_INDEX, [], Closed(False, 0.0)) == (Verdict.NON_STRICT, ["A3"])


def test_not_a_request_may_get_silence_an_error_or_a_close_never_0000() -> None:
    for end in (PROBE, Closed(True, 0.0)):
        assert verdict(GARBAGE, [], end)[0] is Verdict.PASS
    assert verdict(encode_raw(Header(action=0x99)), [ans(Action.NONE, 0x0001)])[0] is Verdict.PASS
    echoed = malformed(encode_raw(Header(transfer_type=0x10, action=0x99)))  # an unknown action echoed, 0000
    v, clauses = verdict(encode_raw(Header(action=0x99)), [echoed])
    assert v is Verdict.FAIL and "A5" in clauses


def test_valid_requests_must_be_answered_once_in_order() -> None:
    assert verdict(POSE, [ans(Action.POSE)]) == (Verdict.PASS, [])
    assert verdict(POSE, [])[0] is Verdict.FAIL  # went on to the probe without answering
    assert verdict(POSE, [ans(Action.POSE), ans(Action.POSE)]) == (Verdict.FAIL, ["A1"])  # answered twice
    assert verdict(POSE, [ans(Action.POSE, 0x1001)]) == (Verdict.FAIL, ["A1"])
    assert verdict(POSE, [ans(Action.POSE)], Closed(False, 0.0))[0] is Verdict.FAIL
    assert verdict(POSE, [ans(Action.POSE)], Silence(5.0)) == (Verdict.FAIL, ["T1"])
    assert verdict(NONE + POSE, [ans(Action.POSE), ans(Action.NONE)])[0] is Verdict.FAIL  # out of order


def test_after_garbage_a_missed_frame_or_a_hang_is_only_non_strict_and_a_close_is_fine() -> None:
    assert verdict(GARBAGE + POSE, []) == (Verdict.NON_STRICT, ["R6"])
    assert verdict(GARBAGE, [], Silence(5.0)) == (Verdict.NON_STRICT, ["R6"])
    assert verdict(GARBAGE + POSE, [], Closed(False, 0.0)) == (Verdict.PASS, [])  # R6: resynchronise or close


def test_the_box_answers_must_be_conforming_frames_and_the_probe_answered_0000() -> None:
    wrong_direction = malformed(encode_raw(Header(transfer_type=0x01, action=Action.POSE)))
    v, clauses = verdict(POSE, [wrong_direction])
    assert v is Verdict.FAIL and "F3" in clauses
    assert verdict(POSE, [ans(Action.POSE)], ans(Action.NONE, 1)) == (Verdict.FAIL, ["A1"])


def test_nan_and_tcp_crc_are_shoulds_and_udp_r7() -> None:
    assert verdict(NAN_POSE, [ans(Action.POSE, 0)]) == (Verdict.NON_STRICT, ["B4"])
    assert verdict(NAN_POSE, [ans(Action.POSE, 0x1001)]) == (Verdict.PASS, [])
    crc = encode(request(Action.NONE), P, Transport.UDP)
    assert verdict(crc, [ans(Action.NONE, 0x0001)]) == (Verdict.NON_STRICT, ["F6"])
    # accepted with a CRC: a CycleOff may still get 0002 (no cycle on: a box may reject it, B-strict-cycle)
    crc_off = encode(request(Action.CYCLE_OFF), P, Transport.UDP)
    assert verdict(crc_off, [ans(Action.CYCLE_OFF, 0x0002)]) == (Verdict.PASS, [])
    crc_pose = encode(request(Action.POSE, pose_blocks([(1.0, 2.0, 3.0, 4.0, 5.0, 6.0)])), P, Transport.UDP)
    assert verdict(crc_pose, [ans(Action.POSE, 0x1001)]) == (Verdict.NON_STRICT, ["F6"])  # a pose: only 0000
    bad_crc = encode_udp(request(Action.NONE))[:-1] + b"\x00"
    assert verdict(bad_crc, [ans(Action.NONE, 0x0001)], transport=Transport.UDP) == (Verdict.NON_STRICT, ["R7"])
    assert verdict(bad_crc, [ans(Action.NONE, 0)], transport=Transport.UDP)[0] is Verdict.FAIL


def test_extension_answers_carry_the_right_values() -> None:
    idx = encode(request(Action.PROG_IDX, value_blocks([7])))
    assert verdict(idx, [ans(Action.PROG_IDX, 0, value_blocks([7]))])[0] is Verdict.PASS
    assert verdict(idx, [ans(Action.PROG_IDX, 0, value_blocks([409]))])[0] is Verdict.PASS
    assert verdict(idx, [ans(Action.PROG_IDX, 0, value_blocks([8]))]) == (Verdict.FAIL, ["E2"])
    bad_27 = encode_raw(Header(action=Action.VISION_RESULT, block_type=3, block_count=1, block_length=5), bytes(5))
    # a malformed 27 answered "400 not understood" in the block is not an answer 0000
    assert verdict(bad_27, [ans(Action.VISION_RESULT, 0, value_blocks([400]))])[0] is Verdict.PASS
    assert verdict(bad_27, [ans(Action.VISION_RESULT, 0, value_blocks([1]))])[0] is Verdict.FAIL
    tol = encode(request(Action.TOLERANCE, tolerance_blocks([0.5])))
    assert verdict(tol, [ans(Action.TOLERANCE)])[0] is Verdict.PASS


def test_a_non_request_may_be_refused_with_its_own_unknown_action_and_a_non_zero_error() -> None:
    """A5: "answer with a non-zero error": echoing the unknown action with FFFF is such an answer."""
    unknown = encode_raw(Header(action=0x03))
    refusal = malformed(encode_raw(Header(transfer_type=0x10, action=0x03, error_code=0xFFFF)))
    assert verdict(unknown, [refusal]) == (Verdict.PASS, [])
    zero = malformed(encode_raw(Header(transfer_type=0x10, action=0x03, error_code=0)))
    assert verdict(unknown, [zero])[0] is Verdict.FAIL  # R1: never 0000 to a non-request
    # the same refusal to a well-formed request pairs with nothing: the request is unanswered
    v, clauses = verdict(POSE, [refusal])
    assert v is Verdict.FAIL and "A1" in clauses


def test_a_refused_26_or_27_needs_no_block_but_a_well_formed_one_still_gets_its_result() -> None:
    """A5: a non-request (version 00 00) answered 27 + FFFF without the ResultCode block is a refusal."""
    bad_version = encode_raw(Header(version=0x0000, action=Action.VISION_RESULT))
    refusal = malformed(encode_raw(Header(transfer_type=0x10, action=Action.VISION_RESULT, error_code=0xFFFF)))
    assert verdict(bad_version, [refusal]) == (Verdict.PASS, [])
    result_request = encode(request(Action.VISION_RESULT))
    v, clauses = verdict(result_request, [refusal])  # E3: a result request is answered with a ResultCode
    assert v is Verdict.FAIL and "E3" in clauses

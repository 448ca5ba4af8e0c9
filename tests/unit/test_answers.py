"""What a box may answer (conformance/protocol/answers.py): each fact pinned to its PROTOCOL.md clause.

The expectations are built from bytes made with the codec (a frame that parses goes to
``rule_for_frame``, one that does not to ``rule_for_error``), then judged with ``judge_answer``
and ``unanswered``. The verdicts these feed (explain.py, the fuzz oracle, the capture
analyser) are tested in their own files; here are the facts themselves.
"""

from __future__ import annotations

from typing import Any

import pytest

from conformance.protocol import (
    Action,
    FloatError,
    Header,
    Profile,
    ProtocolError,
    ResultCode,
    TcpCheckPolicy,
    TransferType,
    Transport,
    answer,
    encode,
    encode_raw,
    parse_frame,
    pose_blocks,
    request,
    tolerance_blocks,
    value_blocks,
)
from conformance.protocol.answers import (
    ALLOWED_CODES,
    SENDABLE_RESULTS,
    Cycle,
    Expectation,
    Rule,
    Seen,
    allowed_codes,
    allowed_values,
    judge_answer,
    request_action,
    rule_for_error,
    rule_for_frame,
    unanswered,
    zero_allowed_for_malformed,
)
from conformance.protocol.levels import Level

STRICT = Profile()
LENIENT = Profile(strict=False)
TCP, UDP = Transport.TCP, Transport.UDP
NAN, INF = float("nan"), float("inf")
A = Action

NONE = encode(request(A.NONE))
POSE = encode(request(A.POSE, pose_blocks([(1.0, 2.0, 3.0, 4.0, 5.0, 6.0)])))
TOL = encode(request(A.TOLERANCE, tolerance_blocks([0.5])))
IDX7 = encode(request(A.PROG_IDX, value_blocks([7])))
RESULT = encode(request(A.VISION_RESULT))
NAN_POSE = encode(request(A.POSE, pose_blocks([(NAN, 0, 0, 0, 0, 0)])))
INF_TOL = encode(request(A.TOLERANCE, tolerance_blocks([INF])))
BAD_INDEX = encode(request(A.POSE, pose_blocks([(0.0,) * 6], first_index=1)))  # B3: the first index is 00


def crc(frame_bytes: bytes) -> bytes:
    """The TCP frame with the correct CRC in its check field instead of 00 00 (F6)."""
    body = frame_bytes[:-2]
    return body + STRICT.check_bytes(body)


def raw(body: bytes = b"", **fields: Any) -> bytes:
    return encode_raw(Header(**fields), body)


def expectation(data: bytes, profile: Profile = STRICT, transport: Transport = TCP, extension: bool = True,
                cycle: Cycle = Cycle.UNKNOWN) -> Expectation:
    """What a box may do with ``data``: parse it as a robot→box frame, then ask answers.py."""
    try:
        frame = parse_frame(data, profile, transport, TransferType.ROBOT_TO_BOX)
    except ProtocolError as exc:
        return rule_for_error(exc, profile, transport, extension)
    return rule_for_frame(frame, profile, transport, extension, cycle)


# -- ALLOWED_CODES / allowed_codes / allowed_values / SENDABLE_RESULTS --------------------------------

ANY = None
CODES = [  # (cycle, action, codes) and the clause each comes from
    *[(c, A.NONE, {0}) for c in Cycle],  # A4: 00 answered 0000
    (Cycle.IDLE, A.CYCLE_ON, {0, 1}),  # S2: 0000, or 0001 not ready
    (Cycle.ON, A.CYCLE_ON, ANY),  # S3: CycleOn twice MAY be an error
    (Cycle.UNKNOWN, A.CYCLE_ON, ANY),  # S3: the state is per box or per connection, a tester can't know
    (Cycle.ON, A.CYCLE_OFF, {0, 2}),  # A3: 0002 CycleOff did not close the detection
    (Cycle.IDLE, A.CYCLE_OFF, ANY),  # S3: CycleOff without CycleOn MAY be an error
    (Cycle.UNKNOWN, A.CYCLE_OFF, ANY),
    *[(c, a, {0}) for c in Cycle for a in (A.POSE, A.REGISTER_POSE, A.TOLERANCE)],  # S3: with or without a cycle
    *[(c, A.PROG_IDX, {0, 409}) for c in Cycle],  # E2: 409 in the block, or in the error field
    *[(c, A.VISION_RESULT, ANY) for c in Cycle],  # E3: the result travels in the block
]


@pytest.mark.parametrize(("cycle", "action", "codes"), CODES, ids=[f"{c.value}-{a.name}" for c, a, _ in CODES])
def test_the_codes_a_well_formed_request_may_get_in_each_cycle_state(cycle: Cycle, action: Action,
                                                                     codes: set[int] | None) -> None:
    want = None if codes is None else frozenset(codes)
    assert ALLOWED_CODES[(cycle, action)] == want
    assert allowed_codes(int(action), cycle) == want


def test_every_cycle_state_and_action_has_an_entry_and_the_default_state_is_unknown() -> None:
    assert set(ALLOWED_CODES) == {(c, a) for c in Cycle for a in A}
    assert len({(c, a) for c, a, _ in CODES}) == len(ALLOWED_CODES)  # the table above pins every entry
    assert allowed_codes(A.CYCLE_OFF) is None and allowed_codes(A.CYCLE_ON) is None
    with pytest.raises(ValueError):
        allowed_codes(0x99)  # A5: not an action, so no well-formed request has it


def test_sendable_results_are_e3s_table_without_the_robots_own_values() -> None:
    assert set(SENDABLE_RESULTS) == {1, 2, 10, 20, 202, 400, 409}
    assert set(SENDABLE_RESULTS) == {int(r) for r in ResultCode} - {ResultCode.EMPTY, ResultCode.NO_ANSWER}


@pytest.mark.parametrize(("frame", "values"), [
    (request(A.PROG_IDX, value_blocks([7])), {7, 409}),  # E2: the same index, or 409
    (request(A.PROG_IDX, value_blocks([-3])), {-3, 409}),  # E1: the int32 is signed
    (request(A.VISION_RESULT), set(SENDABLE_RESULTS)),  # E3
    (request(A.POSE, pose_blocks([(0.0,) * 6])), None),  # A2: no block in the answer to judge
    (request(A.NONE), None),
], ids=["idx7", "idx-negative", "result", "pose", "none"])
def test_the_block_values_an_answer_may_carry(frame: Any, values: set[int] | None) -> None:
    assert allowed_values(frame) == (None if values is None else frozenset(values))


@pytest.mark.parametrize(("header", "action"), [
    (None, None),
    (Header(action=A.POSE), 0x23),
    (Header(action=0x99), 0x99),  # readable, though the action is unknown (A5 decides that)
    (Header(start_word=0xFEFF), None),  # F1
    (Header(version=2), None),  # F2
    (Header(transfer_type=TransferType.BOX_TO_ROBOT), None),  # F3: an answer is not a request
    (Header(transfer_type=0x07), None),
], ids=["none", "pose", "unknown-action", "start-word", "version", "answer", "transfer-07"])
def test_request_action_reads_only_robot_to_box_headers(header: Header | None, action: int | None) -> None:
    assert request_action(header) == action


# -- rule_for_frame / rule_for_error: one table of bytes ---------------------------------------------

# (data, kwargs of expectation(), rule, clause, action, ok_errors, named_error)
EXPECTATIONS = [
    ("valid-none", NONE, {}, Rule.ANSWER, "", 0x00, {0}, None),  # A1, A4
    ("valid-cycle-on-idle", encode(request(A.CYCLE_ON)), {"cycle": Cycle.IDLE}, Rule.ANSWER, "", 0x01, {0, 1}, None),
    ("valid-cycle-off-on", encode(request(A.CYCLE_OFF)), {"cycle": Cycle.ON}, Rule.ANSWER, "", 0x02, {0, 2}, None),
    ("valid-udp", encode(request(A.NONE), STRICT, UDP), {"transport": UDP}, Rule.ANSWER, "", 0x00, {0}, None),
    # F6: a correct CRC in the TCP check field SHOULD be accepted, with the codes the action may get
    ("crc-pose", crc(POSE), {}, Rule.ANSWER_SHOULD, "F6", 0x23, {0}, None),
    ("crc-cycle-off-on", crc(encode(request(A.CYCLE_OFF))), {"cycle": Cycle.ON}, Rule.ANSWER_SHOULD, "F6", 0x02,
     {0, 2}, None),
    ("crc-cycle-off-unknown", crc(encode(request(A.CYCLE_OFF))), {}, Rule.ANSWER_SHOULD, "F6", 0x02, None, None),
    ("crc-cycle-on-idle", crc(encode(request(A.CYCLE_ON))), {"cycle": Cycle.IDLE}, Rule.ANSWER_SHOULD, "F6", 0x01,
     {0, 1}, None),
    ("crc-zero-policy", crc(NONE), {"profile": Profile(tcp_check=TcpCheckPolicy.ZERO)}, Rule.ANY, "F6", 0x00, None, None),
    ("tcp-check-junk", NONE[:-2] + b"\x12\x34", {}, Rule.ANY, "F6", 0x00, None, None),
    # B4: NaN/inf SHOULD be a parse error (answered 1001 / 1002); lenient accepts them
    ("nan-pose-strict", NAN_POSE, {}, Rule.REJECT_SHOULD, "B4", 0x23, None, 0x1001),
    ("inf-tolerance-strict", INF_TOL, {}, Rule.REJECT_SHOULD, "B4", 0x25, None, 0x1002),
    ("nan-pose-lenient", NAN_POSE, {"profile": LENIENT}, Rule.ANY, "B4", 0x23, None, None),
    ("inf-tolerance-lenient", INF_TOL, {"profile": LENIENT}, Rule.ANY, "B4", 0x25, None, None),
    # B3: lenient takes either first index; a box that takes only its own may refuse the other (issue 17)
    ("index-1-lenient", encode(request(A.POSE, pose_blocks([(1, 2, 3, 4, 5, 6)], 1))), {"profile": LENIENT}, Rule.ANY,
     "B3", 0x23, None, None),
    ("index-0-lenient", POSE, {"profile": LENIENT}, Rule.ANSWER, "", 0x23, {0}, None),
    # A3: a parse error under B1-B5 MUST NOT be answered 0000, SHOULD get its action's error
    ("b3-pose", BAD_INDEX, {}, Rule.REJECT, "B3", 0x23, None, 0x1001),
    ("b1-register-pose", raw(bytes(24), action=A.REGISTER_POSE, block_type=1, block_count=1, block_length=24), {},
     Rule.REJECT, "B1", 0x24, None, 0x1001),
    ("b2-tolerance", raw(bytes(4), action=A.TOLERANCE, block_type=2, block_count=1, block_length=4), {},
     Rule.REJECT, "B2", 0x25, None, 0x1002),
    ("b5-tolerance-empty", raw(action=A.TOLERANCE, block_type=2, block_length=5), {}, Rule.REJECT, "B5", 0x25, None,
     0x1002),
    # A3: no code is named for a malformed 00, 01 or 02, nor for 26/27 (E2, E3), nor for a cut frame (F5)
    ("b5-none", raw(bytes(25), action=A.NONE, block_type=1, block_count=1, block_length=25), {}, Rule.REJECT, "B5",
     0x00, None, None),
    ("b5-cycle-on", raw(action=A.CYCLE_ON, block_count=1), {}, Rule.REJECT, "B5", 0x01, None, None),
    ("e2-idx-no-block", raw(action=A.PROG_IDX), {}, Rule.REJECT, "E2", 0x26, None, None),
    ("b3-idx", raw(bytes([1]) + bytes(4), action=A.PROG_IDX, block_type=3, block_count=1, block_length=5), {},
     Rule.REJECT, "B3", 0x26, None, None),
    ("e3-result-block", raw(bytes(5), action=A.VISION_RESULT, block_type=3, block_count=1, block_length=5), {},
     Rule.REJECT, "E3", 0x27, None, None),
    ("f5-cut-pose", POSE[:20], {}, Rule.REJECT, "F5", 0x23, None, None),
    # A5: not a request; never 0000, but silence, an error or a close are fine
    ("f1-garbage", b"hello, world!!", {}, Rule.NOT_REQUEST, "F1", None, None, None),
    ("f2-version", raw(version=2), {}, Rule.NOT_REQUEST, "F2", None, None, None),
    ("f3-answer", encode(answer(A.NONE)), {}, Rule.NOT_REQUEST, "F3", None, None, None),
    ("a5-unknown", raw(action=0x99), {}, Rule.NOT_REQUEST, "A5", 0x99, None, None),
    ("f5-half-header", NONE[:5], {}, Rule.NOT_REQUEST, "F5", None, None, None),
    ("a5-result-no-e", RESULT, {"extension": False}, Rule.NOT_REQUEST, "A5", 0x27, None, None),
    ("a5-bad-idx-no-e", raw(action=A.PROG_IDX), {"extension": False}, Rule.NOT_REQUEST, "A5", 0x26, None, None),
    ("request-error-field", encode(request(A.NONE, error_code=7)), {}, Rule.ANY, "", 0x00, None, None),
    # R7: a UDP datagram with a wrong CRC or length is dropped
    ("udp-bad-crc", encode(request(A.NONE), STRICT, UDP)[:-1] + b"\x00", {"transport": UDP}, Rule.DROP, "F7", 0x00,
     None, None),
    ("udp-trailing", encode(request(A.POSE, pose_blocks([(0.0,) * 6])), STRICT, UDP) + b"\x00", {"transport": UDP},
     Rule.DROP, "F5", 0x23, None, None),
    ("udp-zero-check", NONE, {"transport": UDP}, Rule.DROP, "F7", 0x00, None, None),
    # a malformed and damaged datagram: the malformed request's rule (read header first), or dropped (R7)
    ("udp-b5-short", crc(raw(bytes(50), action=A.POSE, block_type=0x10, block_count=2, block_length=25))[:-3],
     {"transport": UDP}, Rule.REJECT, "B5", 0x23, None, 0x1001),
    ("udp-b5-bad-crc", raw(bytes(50), action=A.POSE, block_type=0x10, block_count=2, block_length=25),
     {"transport": UDP}, Rule.REJECT, "B5", 0x23, None, 0x1001),
    ("udp-b5-crc-ok", crc(raw(bytes(50), action=A.POSE, block_type=0x10, block_count=2, block_length=25)),
     {"transport": UDP}, Rule.REJECT, "B5", 0x23, None, 0x1001),
]


@pytest.mark.parametrize(("data", "kw", "rule", "clause", "action", "ok", "named"), [e[1:] for e in EXPECTATIONS],
                         ids=[e[0] for e in EXPECTATIONS])
def test_what_a_box_may_do_with_these_bytes(data: bytes, kw: dict[str, Any], rule: Rule, clause: str,
                                            action: int | None, ok: set[int] | None, named: int | None) -> None:
    exp = expectation(data, **kw)
    assert (exp.rule, exp.clause, exp.action, exp.named_error) == (rule, clause, action, named)
    assert exp.ok_errors == (None if ok is None else frozenset(ok))
    assert exp.valid is (rule in (Rule.ANSWER, Rule.ANSWER_SHOULD))


@pytest.mark.parametrize(("data", "values"), [
    (IDX7, {7, 409}), (RESULT, set(SENDABLE_RESULTS)), (crc(IDX7), {7, 409}), (crc(RESULT), set(SENDABLE_RESULTS)),
    (POSE, None), (crc(POSE), None),
], ids=["idx", "result", "crc-idx", "crc-result", "pose", "crc-pose"])
def test_an_extension_request_carries_the_values_its_answer_may_hold(data: bytes, values: set[int] | None) -> None:
    """E2/E3 judge the answer's block whether or not the request had a CRC in its check field (F6)."""
    assert expectation(data).values == (None if values is None else frozenset(values))


def test_a_damaged_datagram_that_is_also_malformed_may_be_dropped_or_refused() -> None:
    """The fuzzer's datagrams: B5 with a wrong CRC. A box that checks the CRC first drops it (R7); one
    that reads the header first refuses it like any malformed request (A3: 1001 SHOULD; and for a
    malformed CycleOff any non-zero code). Both are legal; 0000 never is."""
    pose = raw(bytes(50), action=A.POSE, block_type=0x10, block_count=2, block_length=25)
    exp = expectation(pose, transport=UDP)
    assert exp.damaged and "CRC" in exp.message and not expectation(crc(pose), transport=UDP).damaged
    assert unanswered(exp, False, "stayed silent") == []
    assert judge_answer(exp, Seen(action=0x23, error=0x1001)) == []
    assert [f.level for f in judge_answer(exp, Seen(action=0x23, error=0x1002))] == [Level.SHOULD]
    assert [f.level for f in judge_answer(exp, Seen(action=0x23, error=0))] == [Level.MUST]
    cycle_off = expectation(bytes.fromhex("fefe000101020080000000000000"), transport=UDP)
    assert cycle_off.damaged and judge_answer(cycle_off, Seen(action=0x02, error=0x0002)) == []


def test_a_float_error_is_left_open_by_a_lenient_profile() -> None:
    error = FloatError("block 0: non-finite pose value", header=Header(action=A.POSE, block_type=1, block_count=1,
                                                                         block_length=25))
    assert rule_for_error(error, STRICT).rule is Rule.REJECT_SHOULD
    assert rule_for_error(error, LENIENT).rule is Rule.ANY  # B4's SHOULD is not enforced


def test_an_expectation_describes_itself_and_marks_what_follows_an_error() -> None:
    exp = expectation(BAD_INDEX)
    assert exp.describe().startswith("[B3] ") and exp.describe().endswith(" -> reject")
    assert expectation(NONE).describe() == "robot→box NONE err=0x0000 -> answer"
    later = exp.after()
    assert later.after_error and not exp.after_error and later.rule is exp.rule  # R6: the original is unchanged


# -- judge_answer -----------------------------------------------------------------------------------------

E_POSE = expectation(POSE)
E_OFF_ON = expectation(encode(request(A.CYCLE_OFF)), cycle=Cycle.ON)
E_IDX = expectation(IDX7)
E_RESULT = expectation(RESULT)
E_CRC_POSE = expectation(crc(POSE))
E_CRC_OFF = expectation(crc(encode(request(A.CYCLE_OFF))), cycle=Cycle.ON)
E_CRC_IDX = expectation(crc(IDX7))
E_B3 = expectation(BAD_INDEX)
E_B5_ON = expectation(raw(action=A.CYCLE_ON, block_count=1))
E_NAN = expectation(NAN_POSE)
E_F2 = expectation(raw(version=2))
E_A5 = expectation(raw(action=0x99))
E_UDP = expectation(encode(request(A.NONE), STRICT, UDP)[:-1] + b"\x00", transport=UDP)
E_BAD_27 = expectation(raw(bytes(5), action=A.VISION_RESULT, block_type=3, block_count=1, block_length=5))
E_BAD_26 = expectation(raw(action=A.PROG_IDX))
E_ERR_FIELD = expectation(encode(request(A.NONE, error_code=7)))


def seen(action: int | None, error: int | None, value: int | None = None, problem: str = "") -> Seen:
    return Seen(action, error, value, problem, text=f"answered {action} {error} {value}")


# (id, expectation, what the box sent, [(level, clause, key)])
JUDGED = [
    ("pose-0000", E_POSE, seen(0x23, 0), []),
    ("pose-1001", E_POSE, seen(0x23, 0x1001), [("MUST", "A1", "valid/answer/23/code")]),  # A1/S3
    ("off-0002", E_OFF_ON, seen(0x02, 2), []),  # A3
    ("off-0001", E_OFF_ON, seen(0x02, 1), [("MUST", "A1", "valid/answer/02/code")]),
    ("idx-same", E_IDX, seen(0x26, 0, 7), []),  # E2
    ("idx-409-block", E_IDX, seen(0x26, 0, 409), []),
    ("idx-409-error", E_IDX, seen(0x26, 409, 7), []),
    ("idx-other", E_IDX, seen(0x26, 0, 8), [("MUST", "E2", "valid/answer/26/value")]),
    ("idx-bad-code", E_IDX, seen(0x26, 1, 7), [("MUST", "A1", "valid/answer/26/code")]),
    ("result-400", E_RESULT, seen(0x27, 0, 400), []),  # E3
    ("result-any-error", E_RESULT, seen(0x27, 0x1234, 1), []),  # E3: the error field is not judged
    ("result-unknown", E_RESULT, seen(0x27, 0, 5), [("MUST", "E3", "valid/answer/27/value")]),
    ("crc-off-0002", E_CRC_OFF, seen(0x02, 2), []),  # F6: an answer the request itself may get
    ("crc-pose-1001", E_CRC_POSE, seen(0x23, 0x1001), [("SHOULD", "F6", "F6/answer-should/23/code")]),
    ("crc-idx-other", E_CRC_IDX, seen(0x26, 0, 8), [("MUST", "E2", "F6/answer-should/26/value")]),
    # refusing the CRC the E3 way ("400 not understood" in the block) is the F6 SHOULD, not an E2 value
    ("crc-idx-not-understood", E_CRC_IDX, seen(0x26, 0, 400), [("SHOULD", "F6", "F6/answer-should/26/code")]),
    ("b3-1001", E_B3, seen(0x23, 0x1001), []),  # A3
    ("b3-0000", E_B3, seen(0x23, 0), [("MUST", "B3", "B3/reject/23/0000")]),  # A3/R1
    ("b3-1002", E_B3, seen(0x23, 0x1002), [("SHOULD", "A3", "B3/reject/23/code")]),  # A3's SHOULD
    ("b5-cycle-on-any", E_B5_ON, seen(0x01, 5), []),  # A3: no code named for 01
    ("b5-cycle-on-0000", E_B5_ON, seen(0x01, 0), [("MUST", "B5", "B5/reject/01/0000")]),
    ("nan-0000", E_NAN, seen(0x23, 0), [("SHOULD", "B4", "B4/reject-should/23/0000")]),  # B4
    ("nan-1001", E_NAN, seen(0x23, 0x1001), []),
    ("nan-0001", E_NAN, seen(0x23, 1), [("SHOULD", "A3", "B4/reject-should/23/code")]),
    ("f2-0000", E_F2, seen(0x00, 0), [("MUST", "F2", "F2/not-request/-/0000")]),  # A5/R1
    ("f2-error", E_F2, seen(0x00, 1), []),  # A5: a non-zero error is fine
    ("a5-0000", E_A5, seen(0x99, 0), [("MUST", "A5", "A5/not-request/-/0000")]),
    ("udp-0000", E_UDP, seen(0x00, 0), [("MUST", "F7", "F7/drop/00/0000")]),  # R7 MUST
    ("udp-error", E_UDP, seen(0x00, 1), [("SHOULD", "R7", "F7/drop/00/answered")]),  # R7 SHOULD
    ("bad27-400", E_BAD_27, seen(0x27, 0, 400), []),  # E3: "not understood" is not an answer 0000
    ("bad27-ok", E_BAD_27, seen(0x27, 0, 1), [("MUST", "E3", "E3/reject/27/0000")]),
    ("bad26-400", E_BAD_26, seen(0x26, 0, 400), []),
    ("b3-400", E_B3, seen(0x23, 0, 400), [("MUST", "B3", "B3/reject/23/0000")]),  # only 26/27 have ResultCodes
    ("error-field-0000", E_ERR_FIELD, seen(0x00, 0), []),  # PROTOCOL.md is silent: anything goes
    ("error-field-1", E_ERR_FIELD, seen(0x00, 1), []),
    ("broken-answer", E_POSE, seen(0x23, 1, problem="A2"),
     [("MUST", "A2", "answer/A2"), ("MUST", "A1", "valid/answer/23/code")]),
]


@pytest.mark.parametrize(("exp", "answer_seen", "want"), [j[1:] for j in JUDGED], ids=[j[0] for j in JUDGED])
def test_judge_answer(exp: Expectation, answer_seen: Seen, want: list[tuple[str, str, str]]) -> None:
    assert [(f.level, f.clause, f.key) for f in judge_answer(exp, answer_seen)] == want


@pytest.mark.parametrize(("exp", "prefix"), [
    (E_B3, "A3/R1: a request that is a parse error MUST NOT be answered 0000"),
    (E_F2, "A5/R1: a frame that is not a request MUST NOT be answered 0000"),
    (E_UDP, "R7: a datagram with a wrong CRC or length MUST NOT be answered 0000"),
], ids=["reject", "not-request", "drop"])
def test_a_0000_to_bytes_that_break_f_or_b_names_the_rule_and_the_event(exp: Expectation, prefix: str) -> None:
    (finding,) = judge_answer(exp, seen(0, 0))
    assert finding.requirement.startswith(prefix) and exp.message in finding.requirement
    assert finding.observed == "answered 0 0 None"


def test_a_named_error_mismatch_quotes_the_code_a3_names() -> None:
    (finding,) = judge_answer(E_B3, seen(0x23, 0x1002))
    assert "SHOULD be answered 1001" in finding.requirement


@pytest.mark.parametrize(("action", "value", "allowed"), [
    (0x27, 400, True), (0x26, 400, True),  # E3: ResultCode 400, "request not understood"
    (0x27, 1, False), (0x27, None, False), (0x26, 409, False),
    (0x23, 400, False), (None, 400, False),
])
def test_zero_allowed_for_malformed(action: int | None, value: int | None, allowed: bool) -> None:
    assert zero_allowed_for_malformed(action, value) is allowed


# -- unanswered ---------------------------------------------------------------------------------------------

E_PROBE = Expectation(Rule.ANSWER, "", 0x00, "the probe", ok_errors=frozenset({0}), probe=True)
UNANSWERED = [  # (id, expectation, after garbage, [(level, clause, key)])
    ("valid", E_POSE, False, [("MUST", "A1", "valid/answer/23/unanswered")]),  # A1
    ("valid-after-garbage", E_POSE, True, [("SHOULD", "R6", "valid/answer/23/resync")]),  # R6
    ("probe", E_PROBE, False, [("MUST", "A1", "probe/unanswered")]),
    ("probe-after-garbage", E_PROBE, True, [("SHOULD", "R6", "probe/resync")]),
    ("crc", E_CRC_POSE, False, [("SHOULD", "F6", "F6/answer-should/23/unanswered")]),  # F6
    ("b3", E_B3, False, [("SHOULD", "A3", "B3/reject/23/unanswered")]),  # A3: SHOULD be answered 1001
    ("nan", E_NAN, False, [("SHOULD", "A3", "B4/reject-should/23/unanswered")]),
    ("b5-cycle-on", E_B5_ON, False, []),  # A3: silence is fine for a malformed 01
    ("not-request", E_F2, False, []),  # A5: silence is fine
    ("udp", E_UDP, False, []),  # R7: dropped, as it SHOULD be
    ("lenient-nan", expectation(NAN_POSE, LENIENT), False, []),
    ("error-field", E_ERR_FIELD, True, []),
]


@pytest.mark.parametrize(("exp", "after", "want"), [u[1:] for u in UNANSWERED], ids=[u[0] for u in UNANSWERED])
def test_unanswered(exp: Expectation, after: bool, want: list[tuple[str, str, str]]) -> None:
    found = unanswered(exp, after, "stayed silent")
    assert [(f.level, f.clause, f.key) for f in found] == want
    assert all(f.observed == "stayed silent" for f in found)


def test_keys_tell_different_failures_apart_and_the_same_failure_together() -> None:
    rows: dict[str, set[str]] = {}
    for name, exp, answer_seen, _ in JUDGED:
        for f in judge_answer(exp, answer_seen):
            rows.setdefault(f.key, set()).add(name)
    for name, exp, after, _ in UNANSWERED:
        for f in unanswered(exp, after, ""):
            rows.setdefault(f.key, set()).add(name)
    shared = {key: names for key, names in rows.items() if len(names) > 1}  # every other key: one row
    assert shared == {  # the same way of failing, reached twice by the tables above
        "B3/reject/23/0000": {"b3-0000", "b3-400"},
        "valid/answer/23/code": {"pose-1001", "broken-answer"},
    }
    # the same failure on other bytes: one key (unknown actions share "-", so a fuzzer can't flood the report)
    assert judge_answer(expectation(raw(action=0x42)), seen(0x42, 0))[0].key == "A5/not-request/-/0000"
    garbage = [judge_answer(expectation(data), seen(0, 0))[0].key for data in (bytes(14), b"garbage bytes!")]
    assert garbage == ["F1/not-request/-/0000"] * 2
    # the same clause on another action: another key
    tol_b3 = expectation(raw(bytes([1]) + bytes(4), action=A.TOLERANCE, block_type=2, block_count=1, block_length=5))
    assert judge_answer(tol_b3, seen(0x25, 0))[0].key == "B3/reject/25/0000"


def test_the_catalogue_reads_its_expectations_from_the_answer_table() -> None:
    """One answer table: the cases' acceptable codes and values come from protocol/answers, never literals."""
    import re
    from pathlib import Path

    from conformance.harness.client import Answer
    from conformance.protocol import Action, ErrorCode, ResultCode, answer, request
    from conformance.protocol.answers import ALLOWED_CODES, ROBOT_RESULTS, SENDABLE_RESULTS, Cycle
    from conformance.protocol.frames import value_blocks
    from conformance.suite.case_judge import answered_allowed

    def got(action: Action, code: int, value: int | None = None) -> Answer:
        blocks = value_blocks([value]) if value is not None else ()
        return Answer(answer(action, code, blocks), 0.001, b"")

    assert SENDABLE_RESULTS == (1, 2, 10, 20, 202, 400, 409)  # every ResultCode but the robot's own
    assert set(SENDABLE_RESULTS) | set(ROBOT_RESULTS) == {int(r) for r in ResultCode}
    on = answered_allowed(Action.CYCLE_ON, Cycle.IDLE)
    assert on.matches(got(Action.CYCLE_ON, 0)) and on.matches(got(Action.CYCLE_ON, ErrorCode.NOT_READY))
    assert not on.matches(got(Action.CYCLE_ON, 2)) and not on.matches(got(Action.NONE, 0))
    off = answered_allowed(Action.CYCLE_OFF, Cycle.ON)
    assert off.matches(got(Action.CYCLE_OFF, ErrorCode.CYCLE_OFF_FAILED)) and not off.matches(got(Action.CYCLE_OFF, 1))
    assert answered_allowed(Action.CYCLE_ON, Cycle.ON).matches(got(Action.CYCLE_ON, 0x7777))  # S3: a MAY
    for (cycle, action), codes in ALLOWED_CODES.items():
        exp = answered_allowed(action, cycle)
        for code in (0, 1, 2, 0x1001, 0x1002, 409):
            assert exp.matches(got(action, code)) == (codes is None or code in codes), (cycle, action, code)
    result = answered_allowed(Action.VISION_RESULT, request=request(Action.VISION_RESULT))
    assert result.matches(got(Action.VISION_RESULT, 0, 202)) and not result.matches(got(Action.VISION_RESULT, 0, 404))
    cases = Path(__file__).resolve().parents[2] / "conformance" / "cases"
    literal = re.compile(r"answered\([^()]*\[\s*\d")
    assert [p.name for p in cases.glob("*.py") if literal.search(p.read_text())] == []

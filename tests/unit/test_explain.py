"""Judging against every legal framing (conformance/protocol/explain.py): no verdict depends on one framing."""

from __future__ import annotations

from conformance.protocol import Action, Header, Profile, encode, encode_raw, pose_blocks, request
from conformance.protocol.answers import Rule, Seen
from conformance.protocol.explain import explain, explain_events
from conformance.protocol.framings import End

P = Profile()
NONE = encode(request(Action.NONE))
POSE = encode(request(Action.POSE, pose_blocks([(1.0, 2.0, 3.0, 4.0, 5.0, 6.0)])))
#: a header with the right start word and version whose transfer type is FE: a valid NONE begins at its byte 4
HALF_HEADER = b"\xfe\xfe\x00\x01"


def seen(action: int, error: int = 0) -> Seen:
    return Seen(action, error, text=f"answered {action:02X} with {error:04X}")


def clauses(data: bytes, answers: list[Seen], end: End = End.ANSWERED, **kw: object) -> list[tuple[str, str]]:
    return [(f.level, f.clause) for f in explain(data, answers, end, P, **kw).findings]  # type: ignore[arg-type]


def test_a_valid_frame_inside_a_rejected_header_may_be_answered_0000() -> None:
    """The issue's false alarm: fine-grained resynchronisation answers the embedded NONE."""
    data = HALF_HEADER + NONE + POSE
    assert clauses(data, [seen(Action.NONE), seen(Action.POSE)]) == []


def test_skipping_the_whole_rejected_header_is_legal_too() -> None:
    data = HALF_HEADER + NONE + POSE
    result = explain(data, [seen(Action.POSE)], End.ANSWERED, P)
    assert result.findings == [] and "resumes" in result.framing


def test_trusting_the_header_and_waiting_for_its_body_explains_silence() -> None:
    data = HALF_HEADER + NONE + POSE  # the header announces 256 bytes: the probe is swallowed
    assert clauses(data, [], End.SILENT) == []


def test_trusting_a_header_announcing_more_than_the_largest_legal_frame_explains_silence() -> None:
    """R6 (a) bounds no length: a box that trusts a header announcing 255 x 65535 bytes and skips them (counting,
    not buffering: R5) waits for them, with or without a refusal first. It was NON-STRICT R6 ("hangs") in fuzz
    campaigns against tests/impls/selectbox."""
    huge = encode_raw(Header(action=Action.POSE, block_type=1, block_count=255, block_length=0xFFFF))
    assert clauses(huge + NONE, [], End.SILENT) == []
    assert clauses(huge + NONE, [seen(Action.POSE, 0x1001)], End.SILENT) == []
    assert [level for level, _ in clauses(huge + NONE, [seen(Action.POSE, 0)], End.SILENT)] == ["MUST"]  # no 0000


def test_closing_after_bytes_that_are_not_a_request_is_legal() -> None:
    assert clauses(HALF_HEADER + NONE + POSE, [], End.CLOSED) == []
    assert clauses(b"hello" + POSE, [], End.CLOSED) == []


def test_a_0000_that_no_framing_explains_is_a_must() -> None:
    bad = encode_raw(Header(action=Action.POSE, block_type=1, block_count=1, block_length=24), bytes(24))
    found = clauses(bad + NONE, [seen(Action.POSE, 0), seen(Action.NONE)])
    assert ("MUST", "B1") in found or ("MUST", "B5") in found
    assert all(level == "MUST" for level, _ in found)


def test_a_malformed_pose_answered_with_its_error_is_clean() -> None:
    bad = encode_raw(Header(action=Action.POSE, block_type=1, block_count=1, block_length=24), bytes(24))
    assert clauses(bad + NONE, [seen(Action.POSE, 0x1001), seen(Action.NONE)]) == []


def test_a_malformed_answer_to_the_probe_is_the_probe_s_and_judged_as_an_answer() -> None:
    garbage = b"hello"
    broken = Seen(Action.NONE, 0, problem="F2", text="sent a malformed answer: version 01 00")
    found = clauses(garbage + NONE, [broken], probe_at=len(garbage))
    assert found == [("MUST", "F2")]  # not "0000 to bytes that are not a request"


def test_valid_requests_must_be_answered_in_order_without_garbage() -> None:
    assert clauses(POSE + NONE, [seen(Action.NONE)]) == [("MUST", "A1")]
    assert clauses(POSE + NONE, [seen(Action.POSE)], End.SILENT) == [("MUST", "T1")]


def test_a_missed_frame_after_garbage_is_only_a_should() -> None:
    assert clauses(b"hello" + POSE + NONE, [seen(Action.NONE)]) == [("SHOULD", "R6")]


def test_64k_of_fe_then_a_probe() -> None:
    data = b"\xfe" * 65536 + NONE
    assert clauses(data, [seen(Action.NONE)]) == []
    # an error answer to bytes that are not a request is allowed (A5); 0000 is not
    assert clauses(data, [seen(0x00, 0x0001), seen(Action.NONE)]) == []
    assert ("MUST", "F2") in clauses(data, [seen(0x05, 0), seen(Action.NONE)])


def test_a_truncated_frame_at_the_end_of_the_stream() -> None:
    # F5: A3 names no code for a truncated frame; never 0000
    assert clauses(POSE[:20], [], End.CLOSED, eof=True) == []
    assert clauses(POSE[:20], [seen(Action.POSE, 0x1001)], End.CLOSED, eof=True) == []
    assert clauses(POSE[:20], [seen(Action.POSE, 0)], End.CLOSED, eof=True) == [("MUST", "F5")]


def test_events_known_in_advance() -> None:
    from conformance.protocol.answers import Expectation

    valid = Expectation(Rule.ANSWER, "", Action.POSE, "pose", ok_errors=frozenset({0}))
    drop = Expectation(Rule.DROP, "F7", Action.NONE, "bad CRC")
    assert explain_events([drop, valid], [seen(Action.POSE)], End.ANSWERED, independent=True).findings == []
    lost = explain_events([drop, valid], [], End.ANSWERED, independent=True).findings
    assert [(f.level, f.clause) for f in lost] == [("MUST", "A1")]  # a datagram stands alone: no R6 excuse

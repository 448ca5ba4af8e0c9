"""Answers built wrongly and block lengths accepted (pure): the one field isolated, and the titles that name it."""

from __future__ import annotations

from conformance.diagnose import match
from conformance.diagnose.answer_shape import (
    Observed,
    grouped,
    shape_diff,
    shape_title,
    swap_hints,
    swap_story,
    swap_title,
    swapped,
)
from conformance.diagnose.block_length import (
    EXPLAINS,
    grid,
    length_story,
    length_title,
    with_length,
    without_blocks,
    wrong_lengths,
    zero_counts,
    zero_title,
)
from conformance.diagnose.hypotheses import KINDS, Expect, Mechanism
from conformance.model.verdicts import CaseResult, Level, RootCause, Verdict

POSE_REQ = bytes.fromhex("fefe00010123010100190000" "00" "44480000c148000043af2000433400000000000042b40000" "0000")
POSE_ANS = bytes.fromhex("fefe00011023000000000000" "0000")
PROG_REQ = bytes.fromhex("fefe000101260301000500000000000003" "0000")


def test_an_answer_with_the_allowed_fields_shows_no_difference() -> None:
    assert shape_diff(0x23, POSE_REQ, POSE_ANS) is None
    assert shape_diff(0x26, PROG_REQ, bytes.fromhex("fefe000110260301000500000000000003" "0000")) is None


def test_the_request_s_blocks_copied_back_are_named_as_echoed_not_merely_attached() -> None:
    echoed = POSE_REQ[:4] + b"\x10" + POSE_REQ[5:]
    d = shape_diff(0x23, POSE_REQ, echoed)
    assert d is not None and d.field == "echo-blocks" and d.header == bytes.fromhex("01010019")
    other = echoed[:13] + b"\x45" + echoed[14:]  # one data byte differs from the request's
    assert shape_diff(0x23, POSE_REQ, other).field == "blocks-attached"  # type: ignore[union-attr]
    tol = bytes.fromhex("fefe0001012502010005000000" "3f000000" "0000")
    title = shape_title(grouped([d, shape_diff(0x25, tol, tol[:4] + b"\x10" + tol[5:])])[0])  # type: ignore[list-item]
    low = title.lower()
    assert "blocks" in low and "answer" in low and "pose (23) and tolerance (25)" in title


def test_a_progidx_answered_with_the_tolerance_block_type_names_the_block_type_and_e2() -> None:
    wrong = bytes.fromhex("fefe000110260201000500000000000003" "0000")
    d = shape_diff(0x26, PROG_REQ, wrong)
    assert d is not None and (d.field, d.got, d.want) == ("block-type", 2, 3)
    title = shape_title([d])
    assert "ProgIdx (26)" in title and "block type 02" in title and "block type 03" in title and "E2" in title


def test_byte_order_is_confirmed_only_when_swapping_makes_every_answer_legal() -> None:
    pose, cyc_off = Observed(0x23, 0x0110, frozenset({0x1001})), Observed(0x02, 0x0200, frozenset({0, 2}))
    ok, why = swap_story([pose, cyc_off, Observed(0x00, 0, frozenset({0}))])
    assert ok, why
    title = swap_title([pose, cyc_off]).lower()
    assert "error code" in title and "byte order" in title and "1001 goes out as 01 10" in title
    # a 1002 written big-endian contradicts it: the box refuses with 0110, it does not swap
    assert not swap_story([pose, cyc_off, Observed(0x25, 0x1002, frozenset({0x1002}))])[0]
    # one code alone cannot tell "refuses with 0200" from "writes 0002 little-endian"
    assert not swap_story([cyc_off])[0]
    # a code illegal both ways is not byte order
    assert not swap_story([pose, Observed(0x25, 0xFFFF, frozenset({0x1002}))])[0]
    assert swapped(0x1001) == 0x0110


def test_the_block_length_grid_reaches_past_one_byte_and_frames_carry_the_length_they_announce() -> None:
    assert 24 in grid(25) and 26 in grid(25) and 0x119 in grid(25)
    longer = with_length(POSE_REQ, 30)
    assert longer[8:10] == b"\x00\x1e" and len(longer) == 12 + 30 + 2 and longer[12:37] == POSE_REQ[12:37]
    assert len(with_length(POSE_REQ, 24)) == 12 + 24 + 2


def test_the_accepted_lengths_name_the_rule_the_box_applies() -> None:
    at_least = {v: v > 25 for v in grid(25)}
    rule, accepted, refused = length_story(25, at_least)
    assert rule == "at-least" and refused == [24]
    title = length_title(0x23, rule, 25, accepted, refused).lower()
    assert "block length" in title and "25" in title and "l >= 25" in title
    low = {v: v & 0xFF == 25 for v in grid(25)}
    rule, accepted, refused = length_story(25, low)
    assert rule == "low-byte" and "low byte" in length_title(0x23, rule, 25, accepted, refused)
    assert length_story(25, {v: False for v in grid(25)})[0] == ""
    assert length_story(5, {4: True, 6: False, 7: False})[0] == "at-most"


def test_a_wrong_length_is_read_from_cases_answered_0000_only() -> None:
    long = with_length(POSE_REQ, 26)
    zero = CaseResult("B1-02[L26]", "t", ("B1",), Level.MUST, Verdict.FAIL, "m", sent_hex=long.hex(),
                      received_hex=POSE_ANS.hex())
    refused = CaseResult("B1-02[L24]", "t", ("B1",), Level.MUST, Verdict.FAIL, "m",
                         sent_hex=with_length(POSE_REQ, 24).hex(), received_hex="fefe0001102300000000011000 00")
    cause = RootCause("RC1", ("B1",), "t", "e", ["B1-02[L26]", "B1-02[L24]"], kind="wrong-code")
    assert wrong_lengths([cause], [zero, refused]) == {0x23: 26}


def test_the_new_mechanisms_explain_the_root_causes_they_name() -> None:
    assert KINDS.index("error-byte-order") < KINDS.index("refuses-valid")
    m = Mechanism("block-length", frozenset({0x23}), "block-length", "t", ("B1",), ((b"", Expect("invalid", 0x23)),),
                  {"explains": EXPLAINS})
    assert match.explains(m, match.CauseFacts("wrong-code", frozenset({0x23}), frozenset({0x23})))
    assert not match.explains(m, match.CauseFacts("unanswered", frozenset({0x23}), frozenset({0x23})))


def test_the_transfer_type_version_and_progidx_value_of_an_answer_are_compared_too() -> None:
    d = shape_diff(0x23, POSE_REQ, POSE_ANS[:4] + b"\x01" + POSE_ANS[5:])
    assert d is not None and (d.field, d.got) == ("transfer-type", 1) and "transfer type 01" in shape_title([d])
    d = shape_diff(0x23, POSE_REQ, POSE_ANS[:2] + b"\x01\x00" + POSE_ANS[4:])
    assert d is not None and d.field == "version" and "version 01 00" in shape_title([d])
    zero = bytes.fromhex("fefe000110260301000500000000000000" "0000")  # ProgIdx answered with index 0, sent 3
    d = shape_diff(0x26, PROG_REQ, zero)
    assert d is not None and (d.field, d.got, d.want) == ("value", 0, 3) and "ProgIdx (26)" in shape_title([d])
    conflict = bytes.fromhex("fefe000110260301000500000000000199" "0000")  # 409: E2's other legal answer
    assert shape_diff(0x26, PROG_REQ, conflict) is None


def test_the_byte_order_experiment_is_hinted_only_by_a_code_that_is_a_named_code_swapped() -> None:
    swapped_pose = bytes.fromhex("fefe0001102300000000011000 00")
    assert swap_hints([swapped_pose]) == {0x0110}
    assert swap_hints([bytes.fromhex("fefe00011023000000001001 0000"), bytes.fromhex("fefe0001100200000000ffff0000")]) \
        == set()


def test_a_block_count_0_answered_0000_is_read_from_the_cases_and_sent_without_blocks() -> None:
    empty = without_blocks(POSE_REQ)
    assert empty == bytes.fromhex("fefe00010123010000190000" "0000")
    zero = CaseResult("B5-01[pose-N0]", "t", ("B5",), Level.MUST, Verdict.FAIL, "m", sent_hex=empty.hex(" "),
                      received_hex=POSE_ANS.hex(" "))
    refused = CaseResult("B5-01[tolerance-N0]", "t", ("B5",), Level.MUST, Verdict.FAIL, "m",
                         sent_hex="fefe00010125020000050000" "0000", received_hex="fefe00011025000000001002" "0000")
    cause = RootCause("RC1", ("B5",), "t", "e", [zero.id, refused.id], kind="wrong-code")
    assert zero_counts([cause], [zero, refused]) == {0x23}
    title = zero_title([0x23, 0x24]).lower()
    assert "block count 0" in title and "pose (23) and register pose (24)" in title


def test_an_answer_without_blocks_whose_header_still_names_a_block_type_or_length_is_named_by_that_field() -> None:
    typed = shape_diff(0x23, POSE_REQ, bytes.fromhex("fefe00011023010000000000" "0000"))
    assert typed is not None and (typed.field, typed.got, typed.want) == ("block-type", 1, 0)
    assert "block type 01 (and no blocks)" in shape_title([typed])
    long = shape_diff(0x23, POSE_REQ, bytes.fromhex("fefe00011023000000190000" "0000"))
    assert long is not None and (long.field, long.got, long.want) == ("block-length", 25, 0)
    assert "block length 25 where A2" in shape_title([long])


def test_every_block_length_accepted_is_told_as_no_length_check_at_all() -> None:
    rule, accepted, refused = length_story(25, {v: True for v in grid(25)})
    assert rule == "any" and refused == []
    title = length_title(0x23, rule, 25, accepted, refused)
    assert "Does not check the block length" in title and "24 to 537" in title


def test_one_answer_and_a_stray_byte_is_told_from_two_answers() -> None:
    from conformance.diagnose.answer_family import trailing_bytes, trailing_title

    answer = bytes.fromhex("fefe00011000000000000000" "0000")
    assert trailing_bytes(answer + b"\x00", "big") == b"\x00"
    assert trailing_bytes(answer, "big") == b""  # one frame exactly
    assert trailing_bytes(answer + answer, "big") == b""  # two answers: a real extra answer, not a stray byte
    assert trailing_bytes(b"\x00" + answer, "big") == b""  # not an answer first
    title = trailing_title(answer + b"\x00", b"\x00")
    assert "1 extra byte(s) (00)" in title and "15 bytes for a 14-byte frame" in title and "F5" in title


def test_bytes_that_are_not_recognisably_the_answer_show_no_field() -> None:
    # a box flooding random bytes: no start word, or another action, is not this request's answer with one field wrong
    from conformance.diagnose.answer_shape import shape_diff

    none = bytes.fromhex("fefe00010100000000000000" "0000")
    assert shape_diff(0x00, none, bytes.fromhex("a3fe00017700000000000000" "0000")) is None
    assert shape_diff(0x00, none, bytes.fromhex("fefe00017723000000000000" "0000")) is None
    wrong = shape_diff(0x00, none, bytes.fromhex("fefe00010100000000000000" "0000"))
    assert wrong is not None and wrong.field == "transfer-type"

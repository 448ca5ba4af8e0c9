"""Where a stall of the whole box began (pure): the first request of the case's last write left unanswered."""

from __future__ import annotations

from conformance.runtime.box_stall import Stall
from conformance.runtime.stall_point import first_unanswered, frames, word

NONE = bytes.fromhex("fefe000101000000000000000000")
CYCLE_ON = bytes.fromhex("fefe000101010000000000000000")
CYCLE_OFF = bytes.fromhex("fefe000101020000000000000000")
NONE_ANSWER = bytes.fromhex("fefe000110000000000000000000")
POSE = bytes.fromhex("fefe0001012301010019000000" + "44480000" * 6) + b"\x00\x00"


def test_the_only_request_not_covered_by_the_answers_heard_is_where_the_stall_began() -> None:
    assert first_unanswered(NONE + CYCLE_ON, NONE_ANSWER) == 0x01
    assert first_unanswered(CYCLE_ON, b"") == 0x01
    assert first_unanswered(NONE + POSE, NONE_ANSWER) == 0x23  # a frame with blocks is read by its length
    # several left unanswered: a blocked loop may hold answers it wrote, so the wire does not tell which one
    assert first_unanswered(NONE + CYCLE_ON + CYCLE_OFF, NONE_ANSWER) is None
    assert first_unanswered(NONE + CYCLE_ON, b"") is None


def test_every_request_answered_or_no_whole_request_names_nothing() -> None:
    assert first_unanswered(NONE, NONE_ANSWER) is None
    assert first_unanswered(b"\x00\x01\x02", b"") is None
    assert frames(NONE + CYCLE_ON[:7]) == [0x00]  # a cut frame is not a request


def test_the_stall_names_the_request_in_the_protocols_words() -> None:
    assert word(0x01) == "CycleOn (01)" and word(0x77) == "0x77 (77)"
    title = Stall("A1-01", "fe fe", 16, 6.0, "held", 0x01).describe()
    assert title.startswith("The whole box stalled for about 6.0 s on CycleOn (01) (the only request it left "
                            "unanswered), once: case A1-01")

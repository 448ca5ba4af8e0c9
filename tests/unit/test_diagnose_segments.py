"""Segmentation isolated (pure parts): the trials' segments, a frame's fate from what was heard, the judgement of
which difference makes the box fail, and the titles that name it."""

from __future__ import annotations

import pytest

from conformance.diagnose import segment_titles as T
from conformance.diagnose.hypotheses import Heard
from conformance.diagnose.segments import Fate, Finding, fate_of, involved, judge, pieces
from conformance.model.verdicts import CaseResult, Level, Verdict

NONE = bytes.fromhex("fefe000101000000000000000000")
POSE = bytes(range(39))
OK = Fate("ok", 0)


def _heard(action: int, error: int) -> Heard:
    return Heard(action, error, b"")


def test_the_trials_cut_the_pose_where_their_names_say() -> None:
    assert pieces("whole", NONE, POSE) == ([POSE], 0)
    assert pieces("header", NONE, POSE) == ([POSE[:5], POSE[5:]], 0)
    assert pieces("after-header", NONE, POSE) == ([POSE[:12], POSE[12:]], 0)
    assert pieces("blocks", NONE, POSE) == ([POSE[:20], POSE[20:]], 0)
    assert pieces("check", NONE, POSE) == ([POSE[:37], POSE[37:]], 0)
    assert pieces("coalesced", NONE, POSE) == ([NONE + POSE], 1)
    assert pieces("tail-header", NONE, POSE) == ([NONE + POSE[:5], POSE[5:]], 1)


def test_a_frame_unanswered_while_the_tail_behind_it_is_answered_was_dropped() -> None:
    assert fate_of([_heard(0, 0)], False, 0x23, 1) == Fate("dropped")
    assert fate_of([_heard(0, 0), _heard(0, 0)], False, 0x23, 2) == Fate("dropped", None, True)
    assert fate_of([_heard(0, 0)], False, 0x23, 2) == Fate("silent", None, True)
    assert fate_of([], True, 0x23, 1) == Fate("closed")


def test_an_answer_to_the_frame_is_judged_against_the_whole_frame_s_code() -> None:
    assert fate_of([_heard(0x23, 0x1001), _heard(0, 0)], False, 0x23, 1) == Fate("error", 0x1001)
    assert fate_of([_heard(0x23, 0x1001), _heard(0, 0)], False, 0x23, 1, reference=0x1001) == Fate("ok", 0x1001)
    assert fate_of([_heard(0x23, 0), _heard(0, 0), _heard(0, 0)], False, 0x23, 2) == Fate("ok", 0, False)
    assert not Fate("ok", 0, False).ok  # the NONE ahead of it in the segment went unanswered


def test_an_error_answer_with_action_00_is_not_the_tail_s_answer() -> None:
    assert fate_of([_heard(0, 0xFFFF)], True, 0x23, 1) == Fate("closed")


def _all_ok(**bad: Fate) -> dict[str, Fate]:
    fates = {t: OK for t in ("whole", "header", "after-header", "blocks", "check", "coalesced", "tail-header",
                             "tail-blocks")}
    fates.update({k.replace("_", "-"): v for k, v in bad.items()})
    return fates


def test_nothing_is_isolated_when_every_trial_passes_or_the_whole_frame_fails() -> None:
    assert judge(_all_ok()) is None
    assert judge(_all_ok(whole=Fate("dropped"))) is None


def test_a_split_inside_the_header_alone_is_told_from_a_split_anywhere() -> None:
    dropped = Fate("dropped")
    assert judge(_all_ok(header=dropped)) == Finding("split-header", ("header",), dropped)
    every = judge(_all_ok(header=dropped, after_header=dropped, blocks=dropped, check=dropped))
    assert every is not None and every.kind == "split-any"
    assert judge(_all_ok(check=dropped)) == Finding("split-check", ("check",), dropped)
    some = judge(_all_ok(header=dropped, check=dropped))
    assert some == Finding("split-at", ("header", "check"), dropped)


def test_blocks_in_a_later_segment_than_the_header() -> None:
    error = Fate("error", 0x1001)
    found = judge(_all_ok(after_header=error, blocks=error))
    assert found == Finding("split-blocks", ("after-header", "blocks"), error)


def test_several_frames_in_one_segment() -> None:
    found = judge(_all_ok(coalesced=Fate("dropped", None, True), tail_header=Fate("dropped", None, True)))
    assert found is not None and found.kind == "coalesced"


def test_a_partial_frame_at_the_end_of_a_segment_needs_the_same_cut_alone_and_the_coalesced_frames_answered() -> None:
    lost = Fate("dropped", None, True)
    assert judge(_all_ok(tail_header=lost)) == Finding("partial-tail", ("tail-header",), lost)
    fates = _all_ok(tail_header=lost)
    del fates["coalesced"]  # not tried: the story is not told apart from several frames in one segment
    assert judge(fates) is None


@pytest.mark.parametrize(("kind", "fate", "words"), [
    ("split-header", "dropped", ["Never answers a pose (23) split inside its 12-byte header", "R3"]),
    ("split-blocks", "error", ["Answers error 1001 to a pose (23) split between its header and its blocks", "R3"]),
    ("split-any", "closed", ["Closes the connection on a pose (23) split", "R3"]),
    ("split-check", "dropped", ["Never answers a pose (23) split before its check field", "R3"]),
    ("split-at", "error", ["split across TCP segments cut after byte 5 (inside the header), cut before the check"]),
    ("coalesced", "dropped", ["several frames arrive coalesced in one TCP segment", "is never answered", "R4"]),
    ("coalesced", "ok", ["Loses the NONE ahead of a pose (23) in the same TCP segment", "R4"]),
    ("partial-tail", "dropped", ["partial frame at the end of a segment", "is never answered", "R3/R4"]),
    ("partial-tail", "silent", ["partial frame at the end of a segment", "no answer within time_out", "R3/R4"]),
    ("split-header", "silent", ["Gives no answer within time_out to a pose (23) split inside"]),
    ("split-blocks", "late", ["Answers only 6200 ms after its last byte (past time_out) a pose (23) split between"]),
    ("partial-tail", "late", ["is answered only 6200 ms after its last byte (past time_out)"]),
])
def test_titles_name_the_difference_and_what_the_box_does(kind: str, fate: str, words: list[str]) -> None:
    title = T.title(kind, fate, 0x1001 if fate == "error" else None, 0x23, 0, 6200 if fate == "late" else None,
                    ("header", "check"))
    for word in words:
        assert word in title
    assert "unconfirmed" not in title


def test_segmentation_is_asked_for_root_causes_whose_cases_split_or_coalesce_frames() -> None:
    def case(clauses: tuple[str, ...]) -> CaseResult:
        return CaseResult("X-01", "X-01", clauses, Level.MUST, Verdict.FAIL, "seen")

    assert involved([case(("S6", "R4", "A1"))]) and involved([case(("A3",)), case(("R3", "A1"))])
    assert not involved([case(("F7", "R7")), case(("A1", "T1"))])


def test_a_frame_answered_before_its_check_field_then_a_close_is_its_own_fate() -> None:
    # the pose answered like the whole, then the connection closed before the NONE behind it (the check field taken
    # for the start of another frame): not ok, so a split before the check field is isolated
    fate = fate_of([_heard(0x23, 0)], closed=True, action=0x23, nones=1)
    assert fate.kind == "answered-closed" and not fate.ok
    assert fate_of([_heard(0x23, 0), _heard(0, 0)], closed=True, action=0x23, nones=1).ok  # the NONE came: fine
    found = judge({"whole": Fate("ok", 0), "header": Fate("ok", 0), "after-header": Fate("ok", 0),
                   "blocks": Fate("ok", 0), "check": fate})
    assert found is not None and found.kind == "split-check"
    title = T.title(found.kind, fate.kind, fate.code, 0x23, 0)
    assert "check field" in title and "split" in title and "closes the connection" in title

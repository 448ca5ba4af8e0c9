"""The diagnose phase's judgements, pure: what the box did -> which story is confirmed or ruled out."""

from __future__ import annotations

import pytest

from conformance.diagnose import match, titles
from conformance.diagnose.bisect import smallest_refused
from conformance.diagnose.hypotheses import (
    Exchange,
    Expect,
    Heard,
    Mechanism,
    Reading,
    SizeFacts,
    Status,
    answered_well,
    classify_alone,
    echo_story,
    index_candidates,
    size_story,
)
from conformance.diagnose.shrink import shrink, split_frames
from conformance.protocol import Action, Profile, codec_for, request

POSE, TOL, REG, NONE = 0x23, 0x25, 0x24, 0x00


def ok(action: int, error: int = 0) -> Heard:
    return Heard(action, error, bytes([0xFE, 0xFE, 0, 1, 0x10, action, 0, 0, 0, 0, error >> 8, error & 0xFF, 0, 0]))


def ex(*readings: Reading) -> Exchange:
    return Exchange(tuple(b"x" for _ in readings), readings)


# -- one request alone, a NONE after it ----------------------------------------------------------------
def test_an_extra_answer_is_counted_whether_it_comes_at_once_or_after_the_none() -> None:
    assert classify_alone(POSE, ex(Reading((ok(POSE), ok(POSE))), Reading((ok(NONE),)))).kind == "extra"
    late = classify_alone(POSE, ex(Reading((ok(POSE),)), Reading((ok(POSE), ok(NONE)))))
    assert (late.kind, late.count) == ("extra", 2)


def test_a_none_answered_with_the_requests_action_is_no_extra_answer() -> None:
    """A box answering everything with action 23 answers the NONE behind a pose with 23 too."""
    assert classify_alone(POSE, ex(Reading((ok(POSE),)), Reading((ok(POSE),)))).kind == "ok"


def test_a_none_answered_twice_is_not_the_request_before_it_answered_twice() -> None:
    assert classify_alone(TOL, ex(Reading((ok(TOL),)), Reading((ok(NONE), ok(NONE))))).kind == "ok"
    assert classify_alone(NONE, ex(Reading((ok(NONE), ok(NONE))), Reading((ok(NONE), ok(NONE))))).kind == "extra"


def test_echo_refusal_missing_and_a_right_answer_are_told_apart() -> None:
    assert classify_alone(REG, ex(Reading((ok(POSE),)), Reading((ok(NONE),)))).kind == "echo"
    assert classify_alone(TOL, ex(Reading((ok(TOL, 0x1002),)), Reading((ok(NONE),)))).kind == "refused"
    assert classify_alone(TOL, ex(Reading(), Reading((ok(NONE),)))).kind == "missing"
    assert classify_alone(TOL, ex(Reading(), Reading())).kind == "silent"
    assert classify_alone(TOL, ex(Reading((), True))).kind == "closed"
    assert classify_alone(TOL, ex(Reading((ok(TOL),)), Reading((ok(NONE),)))).kind == "ok"


def test_a_cycle_request_refused_by_state_is_legal() -> None:
    """S2: CycleOn may be answered 0001 (not ready); CycleOff 0002 with no cycle on."""
    assert classify_alone(Action.CYCLE_ON, ex(Reading((ok(1, 1),)), Reading((ok(NONE),)))).kind == "ok"
    assert classify_alone(Action.CYCLE_OFF, ex(Reading((ok(2, 2),)), Reading((ok(NONE),)))).kind == "ok"


def test_a_malformed_answer_is_never_a_pose_answered_well() -> None:
    """The cycle experiment compares a pose inside a cycle with one alone: a box whose every answer is malformed
    (wrong transfer type, F3) must look the same in both arms, not 'mishandles poses while no cycle is on' (S3)."""
    bad = Heard(POSE, 0, b"\xfe\xfe", malformed="transfer type 20, expected 10 (F3)")
    assert not answered_well(POSE, (bad,))
    assert classify_alone(POSE, ex(Reading((bad,)), Reading((ok(NONE),)))).kind == "malformed"
    assert answered_well(POSE, (ok(POSE),))
    assert not answered_well(POSE, (ok(POSE, 0x1001),)) and not answered_well(POSE, (ok(POSE), ok(POSE)))


def test_echo_wrong_for_every_action_vs_for_one() -> None:
    every = [classify_alone(a, ex(Reading((ok(0),)), Reading((ok(NONE),)))) for a in (POSE, REG, TOL)]
    assert echo_story(every)[:2] == ("echo-all", 0)
    one = [classify_alone(REG, ex(Reading((ok(POSE),)), Reading((ok(NONE),)))),
           classify_alone(POSE, ex(Reading((ok(POSE),)), Reading((ok(NONE),)))),
           classify_alone(TOL, ex(Reading((ok(TOL),)), Reading((ok(NONE),))))]
    assert echo_story(one) == ("echo-one", None, frozenset({REG}))
    assert echo_story(one[1:])[0] == ""


# -- size: count vs bytes vs index --------------------------------------------------------------------
def statuses(facts: SizeFacts) -> tuple[str, dict[str, Status]]:
    kind, _, stories = size_story(facts)
    return kind, {k: s for k, s, _ in stories}


def test_the_same_count_at_two_block_sizes_is_a_count_limit() -> None:
    kind, st = statuses(SizeFacts({25: 128, 5: 128}, None, 6))
    assert kind == "count-limit"
    assert st == {"count-limit": Status.CONFIRMED, "byte-limit": Status.RULED_OUT, "index": Status.RULED_OUT}


def test_one_byte_size_at_different_counts_is_a_byte_limit() -> None:
    kind, detail, _ = size_story(SizeFacts({25: 41, 5: 203}, None, 6))  # 1039 and 1029 bytes refused
    assert kind == "byte-limit"
    assert (detail["max_bytes"], detail["refused_bytes"]) == (1024, 1029)


def test_a_limit_only_one_block_type_reaches_is_not_confirmed_either_way() -> None:
    """Pose refused from 82 blocks (2064 bytes), tolerance 255 (1289 bytes) accepted: no legal tolerance frame is
    that long, so a byte limit and a pose-only count limit both fit."""
    kind, st = statuses(SizeFacts({25: 82, 5: None}, None, 6))
    assert kind == ""
    assert st["byte-limit"] is Status.CONSISTENT and st["count-limit"] is Status.CONSISTENT


def test_a_count_limit_of_one_block_type_below_the_other_types_bytes() -> None:
    kind, detail, _ = size_story(SizeFacts({25: None, 5: 51}, None, 6))  # tolerance 51 = 269 bytes; pose 255 ok
    assert (kind, detail["threshold"], detail["per_type"]) == ("count-limit", 51, True)


def test_a_wrong_index_accepted_where_acceptance_changes_is_the_index_story() -> None:
    kind, st = statuses(SizeFacts({25: 129, 5: 129}, (129, 0), 1))
    assert kind == "index"
    assert st["count-limit"] is Status.RULED_OUT and st["index"] is Status.CONFIRMED


def test_nothing_refused_rules_every_size_story_out() -> None:
    kind, st = statuses(SizeFacts({25: None, 5: None}))
    assert kind == "" and set(st.values()) == {Status.RULED_OUT}


def test_index_candidates_are_wrong_indexes_a_short_counter_would_expect() -> None:
    values = index_candidates(128, 0)
    assert 0 in values and 128 not in values and 127 in values and 129 in values
    assert index_candidates(16, 1)[0] == (1 + 16) & 0x0F


def test_bisection_pins_the_threshold_in_a_handful_of_requests() -> None:
    asked: list[int] = []

    def accepted(n: int) -> bool:
        asked.append(n)
        return n < 101

    assert smallest_refused(accepted, 1, 255) == 101
    assert len(asked) <= 8
    assert smallest_refused(lambda n: None, 1, 255) is None


# -- shrink, expectations ------------------------------------------------------------------------------
def test_split_then_shrink_keeps_the_fewest_frames_that_still_show_it() -> None:
    codec = codec_for(Profile())
    none, cycle_on = codec.encode(request(Action.NONE)), codec.encode(request(Action.CYCLE_ON))
    frames = split_frames(none + cycle_on + none + b"\x01\x02", codec)
    assert frames == [none, cycle_on, none, b"\x01\x02"]
    kept = shrink(frames, lambda fs: cycle_on in fs and fs[-1] == b"\x01\x02")
    assert kept == [cycle_on, b"\x01\x02"]


def test_expect_names_what_is_outside_the_legal_set() -> None:
    valid = Expect("valid", POSE)
    assert valid.broken_by(Reading((ok(POSE),))) == ""
    assert "2 answers" in valid.broken_by(Reading((ok(POSE), ok(POSE))))
    assert "action 23" in Expect("valid", REG).broken_by(Reading((ok(POSE),)))
    assert "time_out" in valid.broken_by(Reading())
    invalid = Expect("invalid", POSE)
    assert invalid.broken_by(Reading()) == "" and invalid.broken_by(Reading((ok(POSE, 0x1001),))) == ""
    assert "0000" in invalid.broken_by(Reading((ok(POSE),)))
    assert Expect.from_dict(Expect("valid", 1, (0, 1)).to_dict()) == Expect("valid", 1, (0, 1))


# -- which mechanism explains which root cause ---------------------------------------------------------
def mech(kind: str, *actions: int) -> Mechanism:
    return Mechanism(kind, frozenset(actions), "alone", kind, ("A1",), ())


def test_an_extra_answer_explains_wrong_echoes_of_the_requests_after_it() -> None:
    shifted = match.CauseFacts("action-not-echoed", frozenset({TOL, REG, 2}), frozenset({POSE}))
    chosen = match.pick([mech("extra-answer", POSE)], shifted)
    assert chosen is not None and chosen.kind == "extra-answer"
    hyps = match.hypotheses(shifted, "echo never right", chosen, {"extra-answer": (Status.CONFIRMED, "", "alone"),
                                                                  "echo-all": (Status.RULED_OUT, "echoed", "alone")})
    assert [(h.key, h.status) for h in hyps] == [("catalogue", Status.RULED_OUT), ("extra-answer", Status.CONFIRMED),
                                                 ("echo-all", Status.RULED_OUT)]


def test_a_mechanism_of_other_requests_does_not_explain_a_root_cause() -> None:
    facts = match.CauseFacts("wrong-code", frozenset({TOL}), frozenset({TOL}))
    assert match.pick([mech("echo-one", REG)], facts) is None
    hyps = match.hypotheses(facts, "story", None, {"echo-one": (Status.CONFIRMED, "", "alone")})
    assert hyps[0].status is Status.CONSISTENT and hyps[1].status is Status.RULED_OUT


def test_the_more_specific_mechanism_wins() -> None:
    facts = match.CauseFacts("wrong-code", frozenset({POSE}), frozenset({POSE}))
    chosen = match.pick([mech("refuses-valid", POSE), mech("cycle-dependent", POSE)], facts)
    assert chosen is not None and chosen.kind == "cycle-dependent"


# -- titles ---------------------------------------------------------------------------------------------
@pytest.mark.parametrize("n, text", [(128, "count read as signed?"), (101, "of 101 or more blocks (a limit of 100?)")])
def test_a_count_limit_title_names_the_threshold_clause_and_fix(n: int, text: str) -> None:
    title = titles.count_limit(n)
    assert text in title and "B1/B5 allow a block count of 1–255" in title and "—" in title


def test_an_index_title_uses_a_right_ordinal_and_guesses_the_counter() -> None:
    title = titles.index(block=41, value=41 & 0x0F, right=41, threshold=41)
    assert "the 41st block" in title and "41th" not in title and "4-bit" in title


def test_a_fuzz_finding_is_explained_by_the_mechanism_of_the_answers_it_quotes() -> None:
    from conformance.model.verdicts import CaseResult, Level, RootCause, Verdict

    finding = CaseResult("FUZZ-01", "fuzz", ("A1",), Level.MUST, Verdict.FAIL, "A1: two answers",
                         sent_hex="41 41 fe fe 00 01 01 00 00 00 00 00 00 00 00 00",
                         received_hex=(ok(NONE).raw + ok(POSE).raw + ok(POSE).raw).hex(" "))
    cause = RootCause("RC2", ("A1",), "Fuzzing finds the same defect (A1)", "e", ["FUZZ-01"], kind="fuzz")
    facts = match.facts_of(cause, [finding])
    assert NONE in facts.asked and POSE in facts.answered
    chosen = match.pick([mech("extra-answer", POSE)], facts)
    assert chosen is not None and chosen.kind == "extra-answer"


def test_a_size_limit_explains_only_root_causes_whose_requests_reach_it() -> None:
    limit = Mechanism("count-limit", frozenset({POSE, TOL}), "size", "t", ("B5",), (), {"threshold": 101})
    small = match.CauseFacts("unanswered", frozenset({POSE}), frozenset(), most_blocks=1, longest=39)
    big = match.CauseFacts("unanswered", frozenset({POSE}), frozenset(), most_blocks=128, longest=3214)
    assert match.pick([limit], small) is None
    assert match.pick([limit], big) is limit
    assert match.pick([limit], match.CauseFacts("block-position", frozenset(), frozenset())) is limit
    frame = Mechanism("byte-limit", frozenset({POSE}), "size", "t", ("F5",), (), {"max_bytes": 1024})
    assert match.pick([frame], big) is frame and match.pick([frame], small) is None

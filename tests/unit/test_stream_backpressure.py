"""The backpressure cases' pure parts (conformance/cases/stream_backpressure.py): how a burst is sized to the box's pace, and how a
read that ran out of budget is judged: answers still coming are not called lost, but a broken one still is."""

from __future__ import annotations

from conformance.cases.stream_backpressure import BURST_S, MIN_BURST, Backlog, burst_size, judge_answers
from conformance.protocol import Action, answer, encode

POSE_OK = encode(answer(Action.POSE))


def test_a_fast_box_gets_the_whole_burst() -> None:
    assert burst_size(10_000.0, 3000) == 3000


def test_a_slow_box_gets_what_its_pace_answers_in_a_few_seconds() -> None:
    assert burst_size(200.0, 3000) == int(200 * BURST_S)


def test_a_very_slow_box_still_gets_the_minimum_burst() -> None:
    assert burst_size(1.0, 3000) == MIN_BURST
    assert burst_size(0.0, 100) == 100  # never more than asked for


def test_answers_still_coming_when_the_budget_ran_out_are_not_lost() -> None:
    out = Backlog(received=bytearray(POSE_OK * 40), ended="budget")
    assert judge_answers(out, int(Action.POSE), 100) is None


def test_the_same_answers_after_a_silence_are_lost() -> None:
    out = Backlog(received=bytearray(POSE_OK * 40), ended="silent")
    bad = judge_answers(out, int(Action.POSE), 100)
    assert bad is not None and bad.clause == "S6" and "60 lost" in bad.observed


def test_a_frame_cut_short_fails_f5_even_within_the_budget() -> None:
    out = Backlog(received=bytearray(POSE_OK * 3 + POSE_OK[:5] + POSE_OK), ended="budget")
    bad = judge_answers(out, int(Action.POSE), 100)
    assert bad is not None and bad.clause in ("F5", "A1")

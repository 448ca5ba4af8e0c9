"""A run of pipelined answers judged against the requests' actions (conformance/suite/answer_runs.py): the first
lost answer is named when the actions tell it, and only a plain shortfall may be answers still to come."""

from __future__ import annotations

import random

from conformance.protocol import Action, answer, encode
from conformance.suite.answer_runs import Backlog, first_lost, judge_answers

MIXED = [int(a) for a in (Action.POSE, Action.REGISTER_POSE, Action.TOLERANCE, Action.NONE)]


def _actions(n: int, seed: int = 3) -> list[int]:
    rng = random.Random(seed)
    return [rng.choice(MIXED) for _ in range(n)]


def _answers(actions: list[int]) -> bytearray:
    return bytearray(b"".join(encode(answer(Action(a))) for a in actions))


def test_every_answer_in_order_passes() -> None:
    actions = _actions(5000)
    assert judge_answers(Backlog(received=_answers(actions)), actions, 5000) is None


def test_answers_dropped_in_the_middle_are_lost_and_the_first_one_is_named() -> None:
    actions = _actions(3000)
    kept = actions[:1200] + actions[1500:]  # answers 1201 to 1500 never written
    bad = judge_answers(Backlog(received=_answers(kept), ended="silent"), actions, 3000)
    assert bad is not None and bad.clause == "S6" and not bad.shortfall
    assert "answer 1201" in bad.observed and "requests 1501 on" in bad.observed
    assert "first lost answer is" in bad.observed and "1201" in bad.observed.split("first lost answer is")[1]


def test_a_shift_that_leaves_some_actions_unchanged_names_a_range() -> None:
    actions = [0x23, 0x24, 0x25, 0x23, 0x24, 0x23, 0x25, 0x00, 0x24, 0x25, 0x00, 0x23]
    # answer 4 (index 3) lost: answers 4.. are requests 5..; request 3 and 4 differ, so the loss is exactly there
    said = first_lost(actions, actions[4:10], 3, 5)
    assert "request 4's" in said
    same = [0x23, 0x23, 0x23, 0x24, 0x25, 0x00, 0x24]
    said = first_lost(same, same[3:7], 2, 3)  # the answer lost is one of the first three POSEs: they look alike
    assert "one of requests 1 to 3" in said


def test_one_action_throughout_cannot_tell_which_answer_was_lost() -> None:
    pose = [int(Action.POSE)] * 100
    bad = judge_answers(Backlog(received=_answers(pose[:90]), ended="silent"), int(Action.POSE), 100)
    assert bad is not None and bad.clause == "S6" and bad.shortfall and "10 lost" in bad.observed
    assert "first lost" not in bad.observed


def test_fewer_answers_all_matching_name_the_first_missing_request() -> None:
    actions = _actions(400)
    bad = judge_answers(Backlog(received=_answers(actions[:250]), ended="silent"), actions, 400)
    assert bad is not None and bad.shortfall and "the first lost answer is request 251's" in bad.observed


def test_an_answer_cut_short_is_f5_and_never_a_shortfall() -> None:
    actions = _actions(50)
    data = _answers(actions)
    del data[14 * 20 + 5 : 14 * 21]  # answer 21 cut after 5 bytes, the rest follows
    bad = judge_answers(Backlog(received=data, ended="silent"), actions, 50)
    assert bad is not None and bad.clause in ("F5", "A1") and not bad.shortfall


def test_a_wrong_action_no_shift_explains_is_a1() -> None:
    actions = [int(Action.POSE), int(Action.TOLERANCE)] * 10
    got = list(actions)
    got[4] = int(Action.NONE)
    bad = judge_answers(Backlog(received=_answers(got)), actions, 20)
    assert bad is not None and bad.clause == "A1" and "answer 5" in bad.observed

"""conformance.report.clausetext: the clause(s) a verdict judged, and their registry text."""

from __future__ import annotations

import pytest

from conformance.model.verdicts import CaseResult, Level, Verdict
from conformance.protocol.clauses import all_clauses
from conformance.report.clausetext import clause_text, judged_clauses, judged_texts


def _case(requirement: str = "", message: str = "", clauses=("A5", "R1", "F1"), judged=()) -> CaseResult:
    return CaseResult("X-01", "t", clauses, Level.MUST, Verdict.FAIL, message=message, requirement=requirement,
                      judged=judged)


@pytest.mark.parametrize(("requirement", "message", "judged"), [
    ("A5: a frame that is not a request MUST NOT be answered 0000", "", ("A5",)),
    ("A4/T1: the box does not answer a NONE request", "", ("A4", "T1")),
    ("A5, R1, E2 (MUST): without extension E", "", ("A5", "R1", "E2")),
    ("", "R1: vector tc27 breaks F1 and MUST NOT be answered 0000: expected silence", ("R1",)),
    ("", "garbage bytes: no answer", ("A5", "R1", "F1")),  # no prefix: every clause the case cites
    ("the box stopped answering", "F2: malformed", ("F2",)),  # the requirement has none, the message has
    ("", "", ("A5", "R1", "F1")),
])
def test_judged_clauses(requirement, message, judged):
    assert judged_clauses(_case(requirement, message)) == judged


def test_the_suites_own_judged_field_wins():
    case = _case("A5: a frame that is not a request", judged=("R2",))
    assert judged_clauses(case) == ("R2",)


def test_a_clause_named_twice_counts_once():
    assert judged_clauses(_case(clauses=("B3", "B3", "A1"))) == ("B3", "A1")


def test_texts_come_from_the_registry():
    registry = all_clauses()
    for cid, entry in registry.items():
        t = clause_text(cid)
        assert (t.id, t.title, t.level) == (cid, entry.title, "/".join(entry.levels))
        assert t.text == " ".join(entry.text.split()) and "\n" not in t.text
    assert clause_text("F6").level == "/".join(registry["F6"].levels)
    assert [t.id for t in judged_texts(_case("A4/T1: no answer"))] == ["A4", "T1"]


def test_an_unknown_clause_id_still_renders():
    t = clause_text("Z9")
    assert (t.id, t.level) == ("Z9", "") and "Z9" in t.text

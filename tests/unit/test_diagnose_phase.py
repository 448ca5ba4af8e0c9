"""The phase's bookkeeping, pure: titles, order, merging and what a box that cannot be probed gets."""

from __future__ import annotations

from conformance.diagnose import match, titles
from conformance.diagnose.hypotheses import Expect, Mechanism, Status
from conformance.diagnose.phase import _assign, _Lab, diagnose, relink
from conformance.engine.rootcause import SessionFacts
from conformance.model.signature import Reply, Sig, Signature
from conformance.model.verdicts import CaseResult, Level, RootCause, Verdict
from conformance.protocol import Profile

POSE, TOL = 0x23, 0x25


def case(case_id: str, asked: int, answered: int, verdict: Verdict = Verdict.FAIL) -> CaseResult:
    c = CaseResult(case_id, case_id, ("A1",), Level.MUST, verdict, "m")
    c.signature = Signature(Sig.CODE, "X", value="0000", reply=Reply(asked, answered, 0, 0x10))
    return c


def causes() -> tuple[list[RootCause], list[CaseResult]]:
    cases = [case("A-1", TOL, POSE), case("A-2", 0x24, POSE), case("B-1", 0x24, POSE), case("C-1", 0x02, 0x02)]
    found = [RootCause("RC1", ("A2",), "The action is not echoed", "e", ["A-1", "A-2"], kind="action-not-echoed"),
             RootCause("RC2", ("A3",), "wrong code", "e", ["B-1"], kind="wrong-code"),
             RootCause("RC3", ("S1",), "something about CycleOff", "e", ["C-1"], kind="wrong-code"),
             RootCause("RC4", ("S4",), "one at a time", "e", [], kind="one-connection")]
    for rc in found:
        for cid in rc.cases:
            next(c for c in cases if c.id == cid).root_cause = rc.id
    return found, cases


def test_one_mechanism_explains_two_root_causes_they_become_one_and_unconfirmed_ones_come_last() -> None:
    found, cases = causes()
    lab = _Lab()
    extra = Mechanism("extra-answer", frozenset({POSE}), "alone", titles.extra_answer(POSE, 2), ("A1",),
                      ((b"\x01", Expect("valid", POSE)),), {"action": POSE, "count": 2})
    lab.mechanisms.append(extra)
    lab.stories = {"extra-answer": (Status.CONFIRMED, "", "alone"), "echo-all": (Status.RULED_OUT, "echoed", "alone")}
    facts = {rc.id: match.facts_of(rc, cases) for rc in found}
    done = _assign(found, facts, lab, {})
    relink(done.causes, cases)
    assert [rc.title for rc in done.causes] == [
        titles.extra_answer(POSE, 2), "one at a time", "unconfirmed: something about CycleOff"]
    assert [rc.id for rc in done.causes] == ["RC1", "RC2", "RC3"]
    first = done.causes[0]
    assert first.cases == ["A-1", "A-2", "B-1"] and first.kind == "extra-answer" and first.clauses == ("A1",)
    assert {c.id: c.root_cause for c in cases} == {"A-1": "RC1", "A-2": "RC1", "B-1": "RC1", "C-1": "RC3"}
    assert first.diagnosis is not None and first.diagnosis["repro"]["file"] == "rootcause-1.json"
    assert first.diagnosis["catalogue_title"] == "The action is not echoed"
    assert done.causes[1].confirmed is True and done.causes[2].confirmed is False
    assert set(done.repros) == {"RC1"}


def test_a_box_that_stopped_answering_is_not_probed_and_nothing_is_claimed_for_it() -> None:
    found, cases = causes()
    facts = SessionFacts(unresponsive="never answered NONE")
    done = diagnose(found, cases, facts, None, Profile(), 5.0)
    assert done.exchanges == 0
    assert [rc.confirmed for rc in done.causes] == [True, False, False, False]  # the session's finding only
    assert all(rc.title.startswith("unconfirmed: ") for rc in done.causes[1:])


def test_byte_limit_titles_name_a_round_buffer_only_inside_the_measured_window() -> None:
    assert "longer than 1024 bytes" in titles.byte_limit(1024, "x", 1029)
    assert "longer than 512 bytes" in titles.byte_limit(509, "x", 514)
    assert "of 1100 bytes or more (frames of 1090 bytes are accepted)" in titles.byte_limit(1090, "x", 1100)

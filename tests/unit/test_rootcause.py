"""Root causes (conformance/engine/rootcause.py): one defect named once, the one to fix first first.

Runs are built as the suite builds them, without sockets: the box's outcome goes through the
judging routine and :func:`result_of` (so signatures are those real cases produce), the facts
are what the session records, and a run modelling a broken box of tests/impls must satisfy its
expectation as the matrix reads it from summary.json."""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import pytest

from conformance.engine.results import result_of
from conformance.engine.rootcause import SessionFacts, find_root_causes
from conformance.harness.client import Answer, Closed, Malformed, Outcome, Silence
from conformance.model.signature import Death, DeathKind, Sig, Signature
from conformance.model.verdicts import CaseResult, Level, RootCause, SuiteInfo, Verdict
from conformance.protocol import Action, ProtocolError, StreamDecoder, TransferType, answer, encode, request
from conformance.report.summary import write_summary
from conformance.runtime.run_state import S5_TEXT
from conformance.suite.case_judge import CLOSED, NOT_OK, CaseVerdict, Inconclusive, answered, answered_error, judge
from conformance.suite.case_judge import fail as own_verdict
from conformance.suite.record import CaseRecord, Requirement, record
from tests.impls.expectations import EXPECTATIONS
from tests.impls.expectations import judge as blame

NONE, CYCLE_ON, POSE, TOLERANCE = Action.NONE, Action.CYCLE_ON, Action.POSE, Action.TOLERANCE
PARSE_ERROR = "a request that is a parse error MUST NOT be answered 0000"  # A3/R1


# -- building a run ------------------------------------------------------------------------------------
def rec(case_id: str, clauses: str, level: str = "MUST") -> CaseRecord:
    base, _, param = case_id.partition("[")
    info = record(base, clauses.split(), level, f"case {base}", "as PROTOCOL.md says")
    return info.with_param(param.rstrip("]")) if param else info


def raised(case_id: str, clauses: str, exc: CaseVerdict | None, level: str = "MUST", max_open: int = 1) -> CaseResult:
    result = result_of(rec(case_id, clauses, level), None, exc, 0.1)
    result.details["max_open_connections"] = max_open  # what result_of records from the case's transcript
    return result


def judged(case_id: str, clauses: str, outcome: Outcome, requirement: Requirement, level: str = "MUST",
           sent: bytes = b"", max_open: int = 1) -> CaseResult:
    """The result of a case whose outcome the judging routine rejects."""
    with pytest.raises(CaseVerdict) as caught:
        judge(outcome, requirement, Level(level), sent=sent)
    return raised(case_id, clauses, caught.value, level, max_open)


def passed(case_id: str, clauses: str = "A1", max_open: int = 1) -> CaseResult:
    return raised(case_id, clauses, None, max_open=max_open)


def unreachable(case_id: str, since: str) -> CaseResult:
    """A case refused at once: the box has been unreachable since case ``since``."""
    return raised(case_id, "A1", Inconclusive(f"box unreachable since case {since}", signature=Signature.unreachable(since)))


def malformed(raw: bytes) -> Malformed:
    decoder = StreamDecoder(expect=TransferType.BOX_TO_ROBOT)
    decoder.receive_data(raw)
    decoder.receive_data(b"")
    event = decoder.next_event()
    assert isinstance(event, ProtocolError), event
    return Malformed(event, 0.002)


def reply(action: Action, error: int = 0) -> Answer:
    return Answer(answer(action, error), 0.002, encode(answer(action, error)))


def named(words: str) -> tuple[str, ...]:
    """The clauses a test's requirement words start with ("A4/T1: ...", "F2, A1: ...", "[R6] ...")."""
    head = words[1:].partition("]")[0] if words.startswith("[") else words.partition(":")[0]
    return tuple(c.strip() for c in re.split("[/,]", head))


def fail(level: Level, words: str, expected: str, observed: str, **kw: Any) -> CaseVerdict:
    """A case's own verdict, judging the clauses its words name."""
    return own_verdict(level, words, expected, observed, judged=named(words), **kw)


def ok(action: Action, words: str) -> Requirement:
    clauses, _, text = words.partition(": ")
    return Requirement(tuple(clauses.split("/")), text, accept=answered(action, [0]))


def parse_error(action: Action, code: int) -> Requirement:
    """What B1-02, B2-02, B3-02 ... judge: never 0000 (MUST), the action's error (SHOULD)."""
    return Requirement(("A3", "R1"), PARSE_ERROR, accept=NOT_OK, should=answered(action, [code]),
                       should_clauses=("A3",), should_text="a parse error SHOULD be answered with its action's error")


def ids(cases: list[CaseResult], *verdicts: Verdict) -> list[str]:
    return [c.id for c in cases if c.verdict in verdicts]


def marked(cases: list[CaseResult], causes: list[RootCause]) -> None:
    """Every explained case is listed by exactly one root cause and names it; RC1.. in order."""
    assert [c.id for c in causes] == [f"RC{n}" for n in range(1, len(causes) + 1)]
    listed = [i for c in causes for i in c.cases]
    assert len(listed) == len(set(listed))
    for case in cases:
        owner = next((c.id for c in causes if case.id in c.cases), None)
        assert case.root_cause == owner, case.id


def verdict_of(name: str, cases: list[CaseResult], causes: list[RootCause], tmp_path: Path) -> str:
    """What the matrix concludes about box ``name`` from the summary.json of this run."""
    suite = SuiteInfo("test", "2026-01-01T00:00:00Z", 1.0, "127.0.0.1:9", {})
    doc = write_summary(tmp_path / "summary.json", suite, cases, causes)
    return blame(EXPECTATIONS[name], 1, doc["totals"], doc["root_causes"])


# -- no root cause -----------------------------------------------------------------------------------
def test_a_conforming_run_has_no_root_cause_and_findings_that_share_nothing_each_get_one() -> None:
    clean = [passed("A4-01", "A4"), passed("S4-01", "S4 T1", max_open=2), passed("B3-01", "B3"),
             raised("E2-01", "E2 E1", CaseVerdict(Verdict.SKIP, "extension E not implemented"))]
    assert find_root_causes(clean, SessionFacts()) == [] and find_root_causes([]) == []
    assert all(c.root_cause is None for c in clean)
    cases = [
        judged("S3-01", "S3", reply(POSE, 0x0001), ok(POSE, "S3: poses before CycleOn are answered 0000")),
        raised("R4-01", "R4 A1", fail(Level.MUST, "R4: each frame of a segment is answered", "ten answers", "one")),
        raised("S5-02", "S5", fail(Level.MUST, "S5: the box closes its side", "its FIN", "nothing")),
        # the box looked unreachable to two cases, but the session recorded no death: nothing to blame
        unreachable("R3-01[none]", "R2-02"), unreachable("R3-01[pose]", "R2-02"),
    ]
    assert {str(c.signature) for c in cases[1:3]} == {"case:R4-01", "case:S5-02"}  # a case's own finding
    causes = find_root_causes(cases, SessionFacts())
    # no orphan FAIL (issue 34): each FAIL that shares nothing is a root cause of its own, of its clause
    assert sorted((c.clauses[0], tuple(c.cases)) for c in causes) == [
        ("R4", ("R4-01",)), ("S3", ("S3-01",)), ("S5", ("S5-02",))]
    assert next(c for c in causes if c.cases == ["R4-01"]).title.startswith("R4-01: R4: each frame of a segment")
    assert all(c.level is Level.MUST for c in causes)
    assert [c.root_cause for c in cases[3:]] == [None, None]  # INCONCLUSIVE, and no death to blame
    marked(cases, causes)


# -- malformed answers: one defect behind dozens of FAILs ----------------------------------------------
def version_0100(action: Action, error: int = 0) -> Malformed:
    raw = bytearray(encode(answer(action, error)))
    raw[2:4] = b"\x01\x00"
    return malformed(bytes(raw))


def swapped_version_run() -> list[CaseResult]:
    """Every answer carries version 01 00: FAILs in every family (and a case or two that pass)."""
    not_zero = Requirement(("A3", "R1"), PARSE_ERROR, accept=answered_error(POSE))
    cycle_on = Requirement(("S2",), "CycleOn is answered 0000 or 0001", accept=answered(CYCLE_ON, [0, 1]))
    variants = {  # case: (clauses, action, error code the answer carries, requirement, parameters)
        "B1-01": ("B1 B3 A1 S3", POSE, 0, ok(POSE, "B1: poses are answered 0000"), "1-pose 3-pose 255-pose 1-reg"),
        "B3-02": ("B3 A3 R1", POSE, 0x1001, not_zero, "gap-pose repeat-pose wrong-start-pose descending-pose"),
        "B5-01": ("B5 A3 R1", POSE, 0x1001, not_zero, "type-0 count-0 len-24 type-2 len-26"),
        "A1-10": ("A1 A4", POSE, 0, ok(POSE, "A1: valid vectors are answered 0000"), "tc1 tc2 tc3 tc4 tc5 tc6"),
    }
    return [
        judged("T1-00", "A4 T1", version_0100(NONE), ok(NONE, "A4/T1: action 00 is answered 00 0000")),
        judged("F2-01", "F2", version_0100(NONE), ok(NONE, "F2: answers carry version 00 01")),
        passed("F2-02", "F2 A5 R1"),  # a frame with version 00 02 got silence: acceptable
        judged("A4-01", "A4", version_0100(NONE), ok(NONE, "A4: NONE is answered NONE 0000")),
        judged("S2-01", "S2 A1", version_0100(CYCLE_ON), cycle_on),
        judged("S3-01", "S3", version_0100(POSE), ok(POSE, "S3: poses before CycleOn are answered 0000")),
        raised("F4-01", "F4", fail(Level.MUST, "F4: multi-byte fields are big-endian", "00 01", "01 00",
                                   signature=Signature(Sig.ANSWER, clause="F2", field="version", value="0100"))),
        *[judged(f"{case}[{p}]", clauses, version_0100(action, code), requirement)
          for case, (clauses, action, code, requirement, params) in variants.items() for p in params.split()],
        passed("S5-02", "S5"),
        raised("FUZZ-01", "R1 A5", fail(Level.MUST, "F2, A1: the box's answers are conforming frames",
                                        "no failure", "fuzz failure", signature=Signature.fuzz("F2", malformed_answer=True))),
    ]


def test_every_answer_malformed_the_same_way_is_one_root_cause_first(tmp_path: Path) -> None:
    cases = swapped_version_run()
    causes = find_root_causes(cases, SessionFacts())
    failed = ids(cases, Verdict.FAIL)
    assert len(failed) >= 24 and len(causes) == 1
    rc = causes[0]
    assert (rc.clauses, rc.level, rc.kind) == (("F2",), Level.MUST, "malformed-answers")
    assert rc.title == "Every answer of the box is malformed the same way: version 0100 (F2)"
    assert rc.cases == failed and failed[-1] == "FUZZ-01"  # every FAIL, the fuzz finding too, in run order
    assert rc.evidence.startswith("T1-00: sent a malformed answer: [F2] version 0x0100")
    assert "received fe fe 01 00 10 00" in rc.evidence
    marked(cases, causes)
    assert verdict_of("swapped-version", cases, causes, tmp_path) == "ok"


def test_a_fuzz_finding_joins_only_an_unambiguous_malformation(tmp_path: Path) -> None:
    def type_01(case_id: str, byte: int) -> CaseResult:
        raw = bytearray(encode(answer(NONE)))
        raw[4] = byte
        return judged(case_id, "A4", malformed(bytes(raw)), ok(NONE, "A4: NONE is answered NONE 0000"))

    def fuzz(case_id: str) -> CaseResult:
        return raised(case_id, "R1 A5", fail(Level.MUST, "F3: conforming frames", "no failure", "fuzz failure",
                                             signature=Signature.fuzz("F3", malformed_answer=True)))

    one = [type_01("F3-01", 0x01), type_01("A4-01", 0x01), fuzz("FUZZ-01")]
    causes = find_root_causes(one)
    assert [(c.clauses, c.cases) for c in causes] == [(("F3",), ["F3-01", "A4-01", "FUZZ-01"])]
    assert verdict_of("wrong-transfer-type", one, causes, tmp_path) == "ok"
    two = [type_01("F3-01", 0x01), type_01("A4-01", 0x01), type_01("A2-01[none]", 0x00),
           type_01("T1-00", 0x00), fuzz("FUZZ-01")]
    causes = find_root_causes(two)
    assert [c.cases for c in causes[:2]] == [["F3-01", "A4-01"], ["A2-01[none]", "T1-00"]]
    # which of the two it found is not known: the finding is a root cause of its own (no orphan FAIL)
    assert [(c.kind, c.cases) for c in causes[2:]] == [("fuzz", ["FUZZ-01"])]
    marked(two, causes)


def test_error_codes_in_the_other_byte_order(tmp_path: Path) -> None:
    cases = [
        raised("F4-01", "F4", fail(Level.MUST, "F4: multi-byte fields are big-endian (error code)", "10 01",
                                   "01 10: error code in the other byte order", signature=Signature(Sig.SWAPPED, "error-code"))),
        *[judged(f"B3-02[{p}]", "B3 A3 R1", reply(POSE, 0x0110), parse_error(POSE, 0x1001))
          for p in ("gap-pose", "repeat-pose", "wrong-start-pose")],
        judged("B2-02[L4]", "B2 B5 A3 R1", reply(TOLERANCE, 0x0210), parse_error(TOLERANCE, 0x1002)),
        passed("A4-01", "A4"),
    ]
    assert ids(cases, Verdict.NON_STRICT) == [c.id for c in cases[1:5]]  # a SHOULD each; F4-01 is the MUST
    causes = find_root_causes(cases)
    [rc] = causes
    assert (rc.clauses, rc.level, rc.kind) == (("F4", "A3"), Level.MUST, "byte-order")
    assert "1001 goes out as 01 10" in rc.title
    assert rc.cases == ids(cases, Verdict.FAIL, Verdict.NON_STRICT)
    assert rc.evidence.startswith("F4-01: 01 10: error code in the other byte order")
    marked(cases, causes)
    assert verdict_of("swapped-error", cases, causes, tmp_path) == "ok"


def test_a_flood_of_random_bytes_is_blamed_on_its_start_word(tmp_path: Path) -> None:
    garbage = bytes([0x9C, 0x41]) + bytes(range(1, 60))  # the box repeats one random buffer on every connection
    flood = Closed(False, 0.4, flood=70_000)
    cases = [
        *[judged(i, "A4", malformed(garbage), ok(NONE, "A4: NONE is answered NONE 0000"))
          for i in ("T1-00", "A4-01", "F1-01", "F2-01", "F3-01")],
        judged("A1-02", "A1", flood, ok(NONE, "A1: each request is answered once")),
        judged("R3-01[none]", "R3 A1", flood, ok(NONE, "R3: a frame in pieces is answered like the whole")),
    ]
    causes = find_root_causes(cases)
    assert [(c.kind, c.clauses) for c in causes] == [("malformed-answers", ("F1",)), ("closes", ("A1", "R3"))]
    assert causes[0].title.endswith("start 9c41 (F1)")
    assert causes[0].cases == ["T1-00", "A4-01", "F1-01", "F2-01", "F3-01"]
    assert causes[1].title == "The box closes the connection instead of answering NONE"
    assert "kept sending (70000 bytes" in causes[1].evidence
    marked(cases, causes)
    assert verdict_of("flood-random", cases, causes, tmp_path) == "ok"


# -- what the session learnt ---------------------------------------------------------------------------
@pytest.mark.parametrize("detail", ["stayed silent for 5000 ms", "closed or reset the connection"])
def test_a_box_that_never_answers_none_is_one_root_cause(detail: str, tmp_path: Path) -> None:
    """The dead box (accepts, never answers) and a target nobody listens on."""
    t1 = raised("T1-00", "A4 T1", fail(Level.MUST, "A4/T1: the box does not answer a NONE request", "NONE answered",
                                       detail, signature=Signature.unreachable("session start")))
    refused = [unreachable(i, "session start") for i in ("F1-01", "F2-01", "A4-01", "S1-01", "R2-01[random-bytes]")]
    profile = raised("PROFILE-01", "B3 F7 F4", Inconclusive("box unreachable: connection refused"), level="MAY")
    cases = [t1, profile, *refused]
    causes = find_root_causes(cases, SessionFacts(unresponsive=detail))
    [rc] = causes
    assert (rc.clauses, rc.level, rc.kind, rc.evidence) == (("A4", "T1"), Level.MUST, "unresponsive", detail)
    assert rc.title.startswith("The box answers no NONE request in this profile")
    assert rc.cases == ["T1-00", "F1-01", "F2-01", "A4-01", "S1-01", "R2-01[random-bytes]"]
    assert profile.root_cause is None  # unreachable for its own reason: not refused because of the baseline
    marked(cases, causes)
    assert verdict_of("dead", cases, causes, tmp_path) == "ok"
    t1.signature = Signature(Sig.SILENCE, "NONE")  # the baseline case is explained by it whatever its verdict's signature
    assert find_root_causes(cases, SessionFacts(unresponsive=detail))[0].cases[0] == "T1-00"


ONE_AT_A_TIME = ("while a first connection was open, a second connection's NONE request stayed silent for 5000 ms; "
                 "once the first closed, it was answered (answered box→robot NONE err=0x0000)")


def one_at_a_time_run() -> list[CaseResult]:
    late = Silence(5.0)
    return [
        passed("A4-01", "A4"), passed("T2-01", "T2 S6 T1", max_open=2),  # held two connections, and passed
        judged("S4-01", "S4 T1", late, ok(NONE, "S4: a silent stream does not delay command answers"), max_open=2),
        judged("S4-02", "S4 S6 T1", late, ok(NONE, "S4: a busy stream does not delay command answers"), max_open=2),
        judged("R5-01", "R5 T1", late, ok(NONE, "R5: idle connections do not stop the box answering"), max_open=301),
        judged("SEQ-S4", "S4 S6 T1", late, ok(POSE, "S4: command requests answered while streaming"), max_open=2),
        raised("FUZZ-02", "S4 A1", fail(Level.MUST, "S4: fuzzed sessions", "no failure", "fuzz failure",
                                        signature=Signature.fuzz("S4")), max_open=2),
        # a finding of its own on one connection: not explained by S4
        judged("B4-01[pose-qnan-x]", "B4 A3", reply(POSE), Requirement(
            ("B4",), "NaN SHOULD be a parse error", accept=answered_error(POSE)), level="SHOULD"),
    ]


def test_a_box_serving_one_connection_at_a_time_is_blamed_on_s4(tmp_path: Path) -> None:
    cases = one_at_a_time_run()
    causes = find_root_causes(cases, SessionFacts(one_at_a_time=ONE_AT_A_TIME))
    [rc] = causes
    assert (rc.clauses, rc.level, rc.kind, rc.evidence) == (("S4",), Level.MUST, "one-connection", ONE_AT_A_TIME)
    assert rc.cases == ["S4-01", "S4-02", "R5-01", "SEQ-S4", "FUZZ-02"]
    assert cases[-1].root_cause is None and cases[1].root_cause is None  # a NON-STRICT of its own; a PASS
    marked(cases, causes)
    assert verdict_of("one-at-a-time", cases, causes, tmp_path) == "ok"
    # without the preflight's fact the same silences are only silences (SEQ-S4 waited for a POSE answer)
    cases = one_at_a_time_run()
    causes = find_root_causes(cases, SessionFacts())
    assert [(c.kind, c.clauses, c.cases) for c in causes][0] == ("unanswered", ("T1", "S4"), ["S4-01", "S4-02", "R5-01"])
    assert all(c.root_cause for c in cases if c.verdict is Verdict.FAIL)  # SEQ-S4 and FUZZ-02: causes of their own


def test_a_second_connection_refused_is_explained_by_s4_too() -> None:
    """An embedded stack that refuses the second connection: the case ends INCONCLUSIVE at its connect."""
    cases = [*one_at_a_time_run(),
             raised("S4-03", "S4 T1", Inconclusive("box unreachable: connection refused", signature=Signature.unreachable("connect")))]
    [rc] = find_root_causes(cases, SessionFacts(one_at_a_time=ONE_AT_A_TIME))
    assert rc.clauses == ("S4",) and "S4-03" in rc.cases and cases[-1].root_cause == rc.id


LEAK = ("a fresh connection was reset, yet it answers on a connection it accepted earlier: it accepts no new "
        "connections after the suite opened 64 and closed 62")


def test_a_box_that_never_frees_connections_is_blamed_on_s5(tmp_path: Path) -> None:
    killer = "R2-01[random-bytes]"
    s5 = CaseVerdict(Verdict.FAIL, f"S5: the box stopped accepting new connections ({LEAK})", requirement=S5_TEXT,
                     observed=LEAK, judged=("S5",), signature=Signature(Sig.NOT_ACCEPTING))
    after = ["R2-01[64k-of-fe]", "R2-02", "R3-01[none]", "R4-01", "SEQ-S1"]
    cases = [passed("A4-01", "A4"), passed("S5-01", "S5 T1"), raised(killer, "R2 A5", s5),
             *[unreachable(i, killer) for i in after]]
    causes = find_root_causes(cases, SessionFacts(deaths=(Death(killer, DeathKind.CONNECTION_LEAK, LEAK, 64, 62),)))
    [rc] = causes
    assert (rc.clauses, rc.level, rc.kind, rc.evidence) == (("S5", "R2"), Level.MUST, "connection-leak", LEAK)
    assert "after the suite has opened 64 and closed 62" in rc.title
    assert rc.cases == [killer, *after]
    marked(cases, causes)
    assert verdict_of("leaky", cases, causes, tmp_path) == "ok"


def test_each_death_explains_the_cases_after_it_most_explanatory_first() -> None:
    first, second = "B5-01[none-with-pose-block]", "R2-01[64k-of-fe]"
    r2 = CaseVerdict(Verdict.FAIL, "R2: after this case's input the box no longer answers a fresh connection",
                     judged=("R2",), signature=Signature(Sig.DEAD, second))
    cases = [
        passed(first, "B5 A3 R1"),  # it waited out a time_out; the box was gone after it, its own verdict PASS
        unreachable("B5-01[tolerance-type-1]", first),
        passed("F1-01", "F1"),  # re-probed: the box answers again
        raised(second, "R2 A5", r2), *[unreachable(i, second) for i in ("R2-02", "R3-01[none]", "R4-01")],
    ]
    facts = SessionFacts(deaths=(Death(first, DeathKind.DEAD_AFTER_INPUT, "a fresh connection stayed silent", 40, 40),
                                 Death(second, DeathKind.DEAD_AFTER_INPUT, "a fresh connection was refused", 51, 51)))
    causes = find_root_causes(cases, facts)
    assert [(c.kind, c.clauses, c.cases) for c in causes] == [
        ("dead-after-input", ("R2",), [second, "R2-02", "R3-01[none]", "R4-01"]),
        ("dead-after-input", ("R2",), ["B5-01[tolerance-type-1]"]),
    ]
    assert causes[0].title == f"The box stops answering new connections after the input of case {second}"
    assert causes[1].evidence == "a fresh connection stayed silent"
    marked(cases, causes)


# -- silences, and what to fix first -------------------------------------------------------------------
def late_cycle_on_run() -> list[CaseResult]:
    cycle_on = Requirement(("S2",), "CycleOn is answered 0000 or 0001 within time_out", accept=answered(CYCLE_ON, [0, 1]))
    sent = encode(request(CYCLE_ON))
    known = "CYCLE_ON is not answered within time_out (cases S2-01, A3-02): this case depends on it"
    return [
        judged("S2-01", "S2 A1", Silence(5.0), cycle_on, sent=sent),
        judged("A3-02", "A3 S2", Silence(5.0), cycle_on, sent=sent),
        *[raised(i, "S1 S2 T1", Inconclusive(known, signature=Signature(Sig.SILENCE, "CYCLE_ON"))) for i in ("S1-01", "SEQ-S1")],
        passed("T1-00", "A4 T1"),
    ]


def test_a_request_never_answered_in_time_is_blamed_on_t1(tmp_path: Path) -> None:
    cases = late_cycle_on_run()
    causes = find_root_causes(cases)
    [rc] = causes
    assert (rc.clauses, rc.level, rc.kind) == (("T1", "S2"), Level.MUST, "unanswered")
    assert rc.title == "The box does not answer CYCLE_ON within time_out"
    assert rc.cases == ["S2-01", "A3-02", "S1-01", "SEQ-S1"]  # the later ones were not run again
    assert rc.evidence == "S2-01: stayed silent for 5000 ms; sent fe fe 00 01 01 01 00 00 00 00 00 00 00 00"
    marked(cases, causes)
    assert verdict_of("late-cycle-on", cases, causes, tmp_path) == "ok"


def test_a_must_root_cause_comes_before_a_larger_should_one(tmp_path: Path) -> None:
    """Six malformed poses answered 1002 (A3 SHOULD 1001) against CycleOn never answered (MUST):
    the MUST is the defect to fix first, however many cases the SHOULD explains."""
    should = [judged(f"B3-02[{p}]", "B3 A3 R1", reply(POSE, 0x1002), parse_error(POSE, 0x1001)) for p in
              ("gap-pose", "repeat-pose", "wrong-start-pose", "descending-pose", "gap-register-pose", "start-1-pose")]
    cases = should + late_cycle_on_run()
    causes = find_root_causes(cases)
    assert [(c.level, c.kind, len(c.cases)) for c in causes] == [
        (Level.MUST, "unanswered", 4), (Level.SHOULD, "wrong-code", 6)]
    assert causes[1].title == "The box answers POSE with error 0x1002 where the cases expect another code"
    assert causes[1].clauses == ("A3",)
    assert causes[1].cases == [c.id for c in should]
    marked(cases, causes)
    assert verdict_of("late-cycle-on", cases, causes, tmp_path) == "ok"


def test_a_non_strict_only_run_names_the_should_it_broke(tmp_path: Path) -> None:
    """The no-resync box hangs after garbage: R6 (SHOULD) is broken, not T1 (a MUST)."""
    def resync(action: Action) -> Requirement:
        return Requirement(("R6",), "after garbage the box SHOULD resynchronise or close", accept=answered(action, [0]) | CLOSED)

    cases = [judged(f"R6-01[{kind}]", "R6", Silence(5.0), resync(action), level="SHOULD")
             for kind, action in (("ascii", NONE), ("zeros", POSE), ("bad-start-word", POSE), ("bad-version", POSE))]
    cases.append(passed("A5-01[start-fffe]", "A5 R1 F1"))
    fuzz = CaseVerdict(Verdict.NON_STRICT, "[R6] hangs after garbage", signature=Signature.fuzz("R6", key="R6/hang"))
    cases.append(raised("FUZZ-01", "R1 R2 A1 R6", fuzz, level="MUST"))  # fuzzing found the same hang
    assert ids(cases, Verdict.NON_STRICT) == [*(c.id for c in cases[:4]), "FUZZ-01"]
    causes = find_root_causes(cases)
    [rc] = causes
    assert (rc.level, rc.kind, rc.clauses) == (Level.SHOULD, "unanswered", ("R6",))
    # one defect whichever probe went unanswered (NONE behind ascii, POSE behind the others): one root cause
    assert rc.cases == ["R6-01[ascii]", "R6-01[zeros]", "R6-01[bad-start-word]", "R6-01[bad-version]", "FUZZ-01"]
    assert "SHOULD resynchronise" in rc.title and "NONE" not in rc.title
    marked(cases, causes)
    assert verdict_of("no-resync", cases, causes, tmp_path) == "ok"


def test_parse_errors_left_unanswered_are_one_root_cause_whatever_the_action() -> None:
    skipped = Silence(0.2, skipped=True)  # nothing for the bad request; the probe behind it was answered
    cases = [judged("B3-02[gap-pose]", "B3 A3 R1", skipped, parse_error(POSE, 0x1001)),
             judged("B3-02[gap-tolerance]", "B3 A3 R1", skipped, parse_error(TOLERANCE, 0x1002)),
             judged("B1-02[L24-pose]", "B1 B5 A3 R1", skipped, parse_error(POSE, 0x1001))]
    assert [str(c.signature) for c in cases] == ["skipped:POSE", "skipped:TOLERANCE", "skipped:POSE"]
    causes = find_root_causes(cases)
    assert [(c.kind, c.level, c.clauses, c.cases) for c in causes] == [
        ("unanswered-errors", Level.SHOULD, ("A3",), [c.id for c in cases])]
    assert causes[0].title.startswith("The box leaves requests that are parse errors unanswered")


def test_fuzz_findings_that_repeat_are_one_root_cause() -> None:
    def finding(case_id: str, level: Level, key: str) -> CaseResult:
        signature = Signature.fuzz(key) if "/" not in key else Signature.fuzz("R6", key=key)
        words = "R1, A5: 0000 to a frame that is not a request" if level is Level.MUST else "[R6] hangs after garbage"
        return raised(case_id, "R1 A5", fail(level, words, "no failure", "fuzz failure", signature=signature))

    alone = [finding("FUZZ-01", Level.MUST, "R1")]
    [own] = find_root_causes(alone)  # alone, it is still a root cause: no orphan FAIL
    assert (own.kind, own.cases, alone[0].root_cause) == ("fuzz", ["FUZZ-01"], "RC1")
    both = [finding("FUZZ-01", Level.MUST, "R1"), finding("FUZZ-02", Level.MUST, "R1")]
    causes = find_root_causes(both)
    assert [(c.kind, c.title, c.clauses, c.level, c.cases) for c in causes] == [
        ("fuzz", "Fuzzing finds the same defect (R1)", ("R1", "A5"), Level.MUST, ["FUZZ-01", "FUZZ-02"])]
    strict = [finding("FUZZ-01", Level.SHOULD, "end/hang"), finding("FUZZ-02", Level.SHOULD, "end/hang")]
    assert [(c.level, c.clauses) for c in find_root_causes(strict)] == [(Level.SHOULD, ("R6",))]


def test_evidence_quotes_a_bounded_slice_of_what_the_box_did() -> None:
    long = "the box answered " + "x" * 400
    exc = fail(Level.MUST, "S3: poses are answered 0000", "0000", long, sent=b"\x01" * 10,
               received=bytes(range(256)), signature=Signature(Sig.CODE, "POSE", value="0001"))
    cases = [raised("S3-01", "S3", exc), raised("S3-02", "S3", exc)]
    rc = find_root_causes(cases)[0]
    head, received = rc.evidence.split("; received ")
    assert head == f"S3-01: {long}"[:300]
    assert received == bytes(range(256)).hex(" ")[:120]  # (with nothing received: what was sent, see late CycleOn)


def test_on_a_tie_the_cases_defect_comes_before_what_fuzzing_found() -> None:
    """drops-coalesced: two fuzz failures (T1) and two R4 silences: the R4 one names the defect."""
    late = Silence(2.0)
    cases = [
        raised("FUZZ-01", "R1 A1", fail(Level.MUST, "fuzz", "no failure", "fuzz failure", signature=Signature.fuzz("T1"))),
        raised("FUZZ-02", "S4 A1", fail(Level.MUST, "fuzz", "no failure", "fuzz failure", signature=Signature.fuzz("T1"))),
        judged("R4-01", "R4 A1", late, ok(POSE, "R4: request 2 of 10 in one segment is answered")),
        judged("SEQ-R4", "R4 A1", late, ok(POSE, "R4: several frames in one segment are each answered")),
    ]
    causes = find_root_causes(cases)
    assert [c.kind for c in causes] == ["unanswered", "fuzz"] and "R4" in causes[0].clauses

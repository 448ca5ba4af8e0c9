"""No orphan FAIL (issue 34): every FAIL belongs to a root cause, and a run with a FAIL has at least one."""

from __future__ import annotations

from conformance.engine.rootcause import SessionFacts, find_root_causes
from conformance.model.signature import Signature
from conformance.model.verdicts import CaseResult, Level, Verdict
from conformance.protocol import Action
from conformance.suite.case_judge import Inconclusive
from tests.unit.test_rootcause import fail, judged, marked, ok, passed, raised, reply

POSE = Action.POSE


def own(case_id: str, words: str) -> CaseResult:
    return raised(case_id, words.partition(":")[0], fail(Level.MUST, words, "the legal set", "something else"))


def test_a_lone_fail_of_each_kind_is_a_root_cause() -> None:
    cases = [
        passed("A4-01", "A4"),
        judged("S3-01", "S3", reply(POSE, 0x1001), ok(POSE, "S3: poses before CycleOn are answered 0000")),  # a code
        own("T2-01", "T2: the latency does not grow"),  # a timing case's own finding
        raised("FUZZ-01", "R1 A5", fail(Level.MUST, "R1: 0000 to bytes that break B5", "no failure", "a failure",
                                        signature=Signature.fuzz("B5"))),  # a fuzz finding alone
        raised("F7-02", "F7", fail(Level.MUST, "F7: a datagram with a wrong CRC is dropped", "silence", "0000",
                                   signature=None)),  # a FAIL with no signature at all
    ]
    causes = find_root_causes(cases, SessionFacts())
    assert all(c.root_cause for c in cases if c.verdict is Verdict.FAIL) and cases[0].root_cause is None
    assert sorted(i for c in causes for i in c.cases) == ["F7-02", "FUZZ-01", "S3-01", "T2-01"]
    by_case = {c.cases[0]: c for c in causes}
    assert by_case["T2-01"].clauses == ("T2",) and by_case["T2-01"].title.startswith("T2-01: T2: the latency")
    assert by_case["F7-02"].clauses == ("F7",)
    assert by_case["FUZZ-01"].kind == "fuzz"
    marked(cases, causes)


def test_own_findings_of_one_clause_are_one_root_cause_that_counts_them() -> None:
    # (F6, F7 and R7 FAILs are the transport family's: engine/transport_causes groups them before any orphan)
    cases = [own("E2-01", "E2: ProgIdx answered with the index"), own("E2-02", "E2: a conflict is refused"),
             own("R4-01", "R4: each frame of a segment is answered")]
    causes = find_root_causes(cases)
    assert sorted((c.clauses, tuple(c.cases)) for c in causes) == [
        (("E2",), ("E2-01", "E2-02")), (("R4",), ("R4-01",))]
    e2 = next(c for c in causes if c.clauses == ("E2",))
    assert e2.title.endswith("(and 1 more FAIL(s) of E2)")


def test_unreachable_fails_without_a_death_are_one_root_cause() -> None:
    sig = Signature.unreachable("R2-02")
    cases = [raised(f"R3-01[{n}]", "R3", fail(Level.MUST, "R3: a split frame is answered", "an answer", "refused",
                                               signature=sig)) for n in ("none", "pose")]
    cases.append(raised("A1-09", "A1", Inconclusive("box unreachable since case R2-02", signature=sig)))
    [cause] = find_root_causes(cases)
    assert cause.kind == "unreachable" and cause.cases == ["R3-01[none]", "R3-01[pose]"]
    assert "since R2-02" in cause.title and cases[-1].root_cause is None  # INCONCLUSIVE is not a FAIL

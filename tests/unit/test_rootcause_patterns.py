"""Root causes that name the fix (conformance/engine/patterns.py, rootcause.py): a field wrong the same
way in every answer, acceptance that changes at a block position, levels from what a cause explains.

Runs are built as in tests/unit/test_rootcause.py: each outcome goes through the judging routine and
``result_of``, with the bytes a real case sends, so the signatures and quoted bytes are those of a run."""

from __future__ import annotations

import json

from conformance.engine.patterns import Blocks, blocks_of
from conformance.engine.rootcause import SessionFacts, find_root_causes
from conformance.harness.client import Closed, Outcome
from conformance.model.signature import Death, DeathKind, Sig, Signature
from conformance.model.verdicts import CaseResult, Level, Verdict
from conformance.protocol import (
    Action,
    Header,
    TransferType,
    encode,
    encode_raw,
    pose_blocks,
    request,
    tolerance_blocks,
)
from conformance.suite.case_judge import NOT_OK, Inconclusive, answered, fail
from conformance.suite.record import Requirement
from tests.unit.test_rootcause import PARSE_ERROR, judged, malformed, marked, ok, parse_error, passed, raised, reply

NONE, ON, OFF, POSE, REG, TOL = (Action.NONE, Action.CYCLE_ON, Action.CYCLE_OFF, Action.POSE, Action.REGISTER_POSE,
                                 Action.TOLERANCE)
CYCLE_ON = Requirement(("S2",), "CycleOn is answered 0000, or 0001 when not ready", accept=answered(ON, [0, 1]))


def poses(action: Action, n: int, first: int = 0, wrong_at: int | None = None) -> bytes:
    """A pose request of ``n`` blocks as a case sends it; ``wrong_at``: that block's index off by one hundred."""
    raw = bytearray(encode(request(action, pose_blocks([(1.0 * i, 2.0, 3.0, 4.0, 5.0, 6.0) for i in range(n)], first))))
    if wrong_at is not None:
        raw[12 + 25 * wrong_at] = (raw[12 + 25 * wrong_at] + 100) & 0xFF
    return bytes(raw)


def tolerances(n: int, first: int = 0, wrong_at: int | None = None) -> bytes:
    raw = bytearray(encode(request(TOL, tolerance_blocks([0.5] * n, first))))
    if wrong_at is not None:
        raw[12 + 5 * wrong_at] = (raw[12 + 5 * wrong_at] + 100) & 0xFF
    return bytes(raw)


def none_answer(error: int) -> Outcome:
    """Action 00 with ``error``: the right code written with action 00 (a NONE answer carrying an error)."""
    if error == 0:
        return reply(NONE)
    return malformed(encode_raw(Header(transfer_type=TransferType.BOX_TO_ROBOT, error_code=error), b""))


# -- A2: the action never echoed -------------------------------------------------------------------------
def action_00_run() -> list[CaseResult]:
    """A box that answers every request right but writes action 00 in every answer."""
    return [
        passed("T1-00", "A4 T1"), passed("A4-01", "A4"),
        judged("S2-01", "S2 A1", none_answer(0), CYCLE_ON),
        judged("S1-01", "S1", none_answer(0), Requirement(("S1",), "CycleOff is answered", accept=answered(OFF))),
        *[judged(f"B1-01[{n}-pose]", "B1 B3 A1 S3", none_answer(0), ok(POSE, "A1/B1: poses are answered 0000"),
                 sent=poses(POSE, n)) for n in (1, 3, 255)],
        judged("B2-01[1]", "B2 B3 A1 S3", none_answer(0), ok(TOL, "A1/B2: tolerances are answered 0000"),
               sent=tolerances(1)),
        *[judged(f"B3-02[{p}-pose]", "B3 A3 R1", none_answer(0x1001), parse_error(POSE, 0x1001),
                 sent=poses(POSE, 3, wrong_at=1)) for p in ("gap", "repeat")],
        judged("B2-02[L4]", "B2 B5 A3 R1", none_answer(0x1002), parse_error(TOL, 0x1002)),
        judged("A5-01[0x30]", "A5 R1", none_answer(0), Requirement(("A5", "R1"), "never 0000", accept=NOT_OK)),
    ]


def test_a_box_that_never_echoes_the_action_gets_one_a2_root_cause_first() -> None:
    cases = action_00_run()
    assert {str(c.signature) for c in cases if c.signature} >= {"code:NONE:0000", "answer:A4:none-error=1001"}
    causes = find_root_causes(cases, SessionFacts())
    first = causes[0]
    assert (first.clauses, first.kind, first.level) == (("A2",), "action-not-echoed", Level.MUST)
    assert first.title.startswith("The action is not echoed: the box answers every request with action 00")
    assert "CYCLE_ON, CYCLE_OFF, POSE, TOLERANCE" in first.title
    # every case the box failed by writing 00 where it was asked another action, and nothing else
    assert first.cases == [c.id for c in cases if c.verdict in (Verdict.FAIL, Verdict.NON_STRICT)
                           and c.id != "A5-01[0x30]"]
    # the old first cause ("answers NONE with error 0x0000") is gone; the 0000 to an unknown action is its own
    assert [(c.kind, c.cases) for c in causes[1:]] == [("wrong-code", ["A5-01[0x30]"])]
    marked(cases, causes)


def test_a_single_action_answered_with_another_is_not_a_field_wide_cause() -> None:
    """One action answered wrongly (TOLERANCE with action 00): a case-level group, not A2."""
    cases = [judged(f"B2-01[{n}]", "B2 B3 A1 S3", none_answer(0), ok(TOL, "A1/B2: tolerances are answered 0000"),
                    sent=tolerances(n)) for n in (1, 3, 255)]
    causes = find_root_causes(cases)
    assert [c.kind for c in causes] == ["wrong-code"]


# -- A3/A4: one error code whatever the action -----------------------------------------------------------
def test_one_error_code_for_every_action_is_one_root_cause_of_the_level_it_explains() -> None:
    """A box that answers every parse error 0003: the A3 SHOULD broken for poses, register poses and
    tolerances alike is one cause (SHOULD: it explains NON-STRICT verdicts only)."""
    cases = [
        *[judged(f"B3-02[{p}-pose]", "B3 A3 R1", reply(POSE, 3), parse_error(POSE, 0x1001), sent=poses(POSE, 3, 0, 1))
          for p in ("gap", "repeat", "descending")],
        judged("B3-02[gap-reg]", "B3 A3 R1", reply(REG, 3), parse_error(REG, 0x1001), sent=poses(REG, 3, 0, 1)),
        judged("B2-02[L4]", "B2 B5 A3 R1", reply(TOL, 3), parse_error(TOL, 0x1002)),
        passed("B1-01[1-pose]", "B1"),
    ]
    assert {c.verdict for c in cases[:-1]} == {Verdict.NON_STRICT}
    [cause] = find_root_causes(cases)
    assert (cause.kind, cause.clauses, cause.level) == ("constant-error", ("A3",), Level.SHOULD)
    assert cause.title.startswith("The box answers error 0x0003 whatever the action")
    assert cause.cases == [c.id for c in cases[:-1]]


def test_every_request_refused_with_one_code_names_a3_and_a4_at_must() -> None:
    """Every request answered 0001 (never ready): NONE (A4), poses and tolerances (A3) fail alike."""
    cases = [
        judged("A4-01", "A4", none_answer(1), ok(NONE, "A4: NONE is answered 0000")),
        judged("S3-01", "S3", reply(POSE, 1), ok(POSE, "S3: poses are answered 0000"), sent=poses(POSE, 1)),
        judged("B2-01[1]", "B2 A1", reply(TOL, 1), ok(TOL, "A1/B2: tolerances are answered 0000"), sent=tolerances(1)),
        judged("B1-01[1-reg]", "B1 A1", reply(REG, 1), ok(REG, "A1/B1: poses are answered 0000"), sent=poses(REG, 1)),
    ]
    causes = find_root_causes(cases)
    assert causes[0].kind == "constant-error" and causes[0].clauses == ("A3", "A4") and causes[0].level is Level.MUST
    assert "0x0001" in causes[0].title and set(causes[0].cases) == {c.id for c in cases}


# -- B3: acceptance that changes at a block position ----------------------------------------------------
def test_the_blocks_of_a_quoted_request() -> None:
    assert blocks_of(poses(POSE, 3).hex(" "), 0) == Blocks(POSE, 3, None)
    assert blocks_of(poses(POSE, 3, first=1).hex(" "), 1) == Blocks(POSE, 3, None)
    assert blocks_of(poses(POSE, 3, first=1).hex(" "), 0) is None  # every index off: not one wrong index
    assert blocks_of(tolerances(20, wrong_at=16).hex(" "), 0) == Blocks(TOL, 20, 16)
    long = poses(POSE, 255)  # 6389 bytes: a verdict quotes 4096 and says how many there were
    quoted = long[:4096].hex(" ") + f" … ({len(long)} bytes in all)"
    assert blocks_of(quoted, 0) == Blocks(POSE, 255, None)
    assert blocks_of(quoted.replace("6389", "6388"), 0) is None  # the header and the length disagree
    assert blocks_of(encode(request(NONE)).hex(" "), 0) is None and blocks_of("zz", 0) is None


def modulo_16_run(first: int = 0, boundaries: bool = True) -> list[CaseResult]:
    """A box that counts block indexes in 4 bits: a valid request of 17+ blocks is refused, a wrong
    index at the 17th block (position 16) accepted; everything up to 16 blocks is judged right."""
    pose_ok = ok(POSE, "A1/B1: a well-formed pose request with {count} block(s) is answered 0000")
    tol_ok = ok(TOL, "A1/B2: a well-formed tolerance request is answered 0000")
    cases = [
        passed("B1-01[1-pose]", "B1"), passed("B1-01[3-pose]", "B1"),
        judged("B1-01[255-pose]", "B1 B3 A1 S3", reply(POSE, 0x1001), pose_ok, sent=poses(POSE, 255, first)),
        judged("B1-01[255-reg]", "B1 B3 A1 S3", reply(REG, 0x1001), ok(REG, "A1/B1: register poses"),
               sent=poses(REG, 255, first)),
        judged("B2-01[255]", "B2 B3 A1 S3", reply(TOL, 0x1002), tol_ok, sent=tolerances(255, first)),
        passed("B3-02[gap-pose]", "B3 A3 R1"),
        judged("A3-02[tol]", "A3", reply(TOL, 0x0001), tol_ok),  # another defect: a group of its own, or none
    ]
    if boundaries:  # what the boundary cases (block counts 1..255, a wrong index at the 17th) add
        cases += [
            passed("BND-01[16-pose]", "B1 B3"),
            judged("BND-01[17-pose]", "B1 B3 A1", reply(POSE, 0x1001), pose_ok, sent=poses(POSE, 17, first)),
            judged("BND-02[wrong-17th-pose]", "B3 R1", reply(POSE, 0), parse_error(POSE, 0x1001),
                   sent=poses(POSE, 20, first, wrong_at=16)),
            judged("BND-02[wrong-129th-tol]", "B3 R1", reply(TOL, 0), parse_error(TOL, 0x1002),
                   sent=tolerances(200, first, wrong_at=128)),
        ]
    return cases


def test_a_box_counting_indexes_in_four_bits_gets_one_b3_root_cause_naming_the_position() -> None:
    cases = modulo_16_run()
    causes = find_root_causes(cases, SessionFacts())
    first = causes[0]
    assert (first.clauses, first.kind, first.level) == (("B3",), "block-position", Level.MUST)
    assert "from the 17th block on" in first.title
    assert "refuses valid requests of 17, 255 blocks" in first.title and "wrong index at block 17, 129" in first.title
    assert first.cases == ["B1-01[255-pose]", "B1-01[255-reg]", "B2-01[255]", "BND-01[17-pose]",
                           "BND-02[wrong-17th-pose]", "BND-02[wrong-129th-tol]"]
    assert first.evidence.startswith("BND-01[17-pose]")  # the lowest position shown
    assert all(c.root_cause == "RC1" for c in cases if c.verdict is Verdict.FAIL and "B3" in c.judged)
    marked(cases, causes)


def test_with_the_catalogue_of_today_the_b3_cause_says_what_it_knows() -> None:
    """Only the 255-block cases fail: the position is bounded, not named; still one B3 cause, first."""
    cases = modulo_16_run(first=1, boundaries=False)
    causes = find_root_causes(cases, SessionFacts(first_index=1))
    assert causes[0].kind == "block-position" and causes[0].clauses == ("B3",)
    assert "at some block up to the 255th block" in causes[0].title and "indexes 1, 2, …" in causes[0].title
    assert causes[0].cases == ["B1-01[255-pose]", "B1-01[255-reg]", "B2-01[255]"]
    # read with the wrong first index, every block of those requests is off: no position to name
    assert all(c.kind != "block-position" for c in find_root_causes(modulo_16_run(1, False), SessionFacts()))


def test_a_box_refusing_every_block_request_has_no_position() -> None:
    cases = [judged(f"B1-01[{n}-pose]", "B1 B3 A1 S3", reply(POSE, 0x1001), ok(POSE, "A1/B1: poses"),
                    sent=poses(POSE, n)) for n in (1, 3, 255)]
    assert all(c.kind != "block-position" for c in find_root_causes(cases))
    closed = judged("B1-01[17-pose]", "B1 A1", Closed(True, 0.01), ok(POSE, "A1/B1: poses"), sent=poses(POSE, 17))
    answered_ok = judged("B1-01[3-pose]", "B1 A1", reply(POSE, 0x1001), ok(POSE, "A1/B1: poses"), sent=poses(POSE, 3))
    [cause] = [c for c in find_root_causes([closed, answered_ok]) if c.kind == "block-position"]
    assert "up to the 3rd block" in cause.title and cause.cases == ["B1-01[17-pose]", "B1-01[3-pose]"]


# -- levels, and every FAIL ------------------------------------------------------------------------------
def test_a_root_cause_has_the_level_of_what_it_explains() -> None:
    """A death that explains only INCONCLUSIVE verdicts and a NON-STRICT one is no MUST root cause."""
    cases = [
        raised("R6-01", "R6", Inconclusive("box unreachable after the case")),
        *[raised(f"S{n}-01", "S1", Inconclusive("box unreachable since case R6-01",
                                                 signature=Signature.unreachable("R6-01"))) for n in (1, 2)],
    ]
    facts = SessionFacts(deaths=(Death("R6-01", DeathKind.DEAD_AFTER_INPUT, "a fresh connection stayed silent", 9, 9),))
    [cause] = find_root_causes(cases, facts)
    assert cause.level is Level.SHOULD and cause.cases == ["R6-01", "S1-01", "S2-01"]
    cases[0] = raised("R6-01", "R6", fail(Level.MUST, "R2: the box keeps answering", "an answer", "silence"))
    assert [c.level for c in find_root_causes(cases, facts)] == [Level.MUST]  # now it explains a FAIL
    for cause in find_root_causes(action_00_run()) + find_root_causes(modulo_16_run()):
        explained = [c for c in action_00_run() + modulo_16_run() if c.id in cause.cases]
        assert (cause.level is Level.MUST) == any(c.verdict is Verdict.FAIL for c in explained), cause


def test_every_fail_of_a_realistic_run_belongs_to_a_root_cause() -> None:
    """The FAILs the field and position causes explain all join them; a FAIL of another defect (0000 to an
    unknown action, A5/R1: not an echo problem; a CycleOn-state code) is a root cause of its own (issue 34)."""
    for cases, alone in ((action_00_run(), {"A5-01[0x30]"}), (modulo_16_run(), {"A3-02[tol]"})):
        causes = find_root_causes(cases)
        assert all(c.root_cause for c in cases if c.verdict is Verdict.FAIL)
        own = [c for c in causes if set(c.cases) & alone]
        assert [set(c.cases) for c in own] == [alone] and own[0].level is Level.MUST


def test_facts_cross_pytest_xdist_as_json() -> None:
    facts = SessionFacts("NONE unanswered", "", (Death("B1-02", DeathKind.CONNECTION_LEAK, "refused", 64, 62),), 1)
    again = SessionFacts.from_dict(json.loads(json.dumps(facts.to_dict())))
    assert again == facts and again.deaths[0].kind is DeathKind.CONNECTION_LEAK
    other = SessionFacts("", "one at a time", (Death("C-3", DeathKind.DEAD_AFTER_INPUT, "silent", 70, 70),))
    merged = again.merged(other)
    assert (merged.unresponsive, merged.one_at_a_time, [d.case_id for d in merged.deaths]) == (
        "NONE unanswered", "one at a time", ["B1-02", "C-3"])
    sig = Signature(Sig.CODE, "NONE", value="0000")
    assert Signature.from_dict(json.loads(json.dumps(sig.to_dict()))) == sig and str(sig) == "code:NONE:0000"
    assert PARSE_ERROR.startswith("a request that is a parse error")


def test_a_field_wrong_in_every_answer_comes_before_a_larger_case_level_group() -> None:
    """A constant transfer type (F3) in every answer is named first, before a case-level group that happens to
    hold more cases (tolerances refused with 0001): the field is what the vendor fixes first."""
    def type_01(case_id: str) -> CaseResult:
        return judged(case_id, "A4", malformed(encode(request(NONE))), ok(NONE, "A4: NONE is answered NONE 0000"))

    cases = [type_01("F3-01"), type_01("A4-01"),
             *[judged(f"B2-01[{n}]", "B2 A1", reply(TOL, 1), ok(TOL, "A1/B2: tolerances are answered 0000"),
                      sent=tolerances(n)) for n in (1, 3, 255)]]
    causes = find_root_causes(cases)
    assert [(c.kind, c.clauses) for c in causes] == [("malformed-answers", ("F3",)), ("wrong-code", ("A1", "B2"))]
    assert causes[0].title == "Every answer of the box is malformed the same way: transfer type 01 (F3)"


def test_a_fuzz_finding_on_a_block_request_joins_the_b3_position_cause() -> None:
    """FUZZ-01 quotes the request, not the answer: a valid 17-block pose it found refused is the same
    B3 defect as the catalogue's (found against a box counting indexes in 4 bits)."""
    from conformance.suite.case_judge import CaseVerdict

    fuzz = raised("FUZZ-01", "R1 R2 A1 A3", CaseVerdict(
        Verdict.FAIL, "A1: a well-formed request (POSE ×17) is answered 0000; the box answered 1001",
        sent=poses(POSE, 17), signature=Signature.fuzz("A1"), judged=("A1", "A3")))
    cases = [*modulo_16_run(boundaries=False), fuzz]
    causes = find_root_causes(cases, SessionFacts())
    assert causes[0].kind == "block-position" and "FUZZ-01" in causes[0].cases
    assert "from the 17th block on" not in causes[0].title and "17, 255 blocks" in causes[0].title
    # a fuzz finding about a wrong index answered 0000 counts as accepted at that position
    wrong = raised("FUZZ-01", "R1 B3", CaseVerdict(
        Verdict.FAIL, "R1: a request with a wrong index MUST NOT be answered 0000", sent=poses(POSE, 20, wrong_at=16),
        signature=Signature.fuzz("R1"), judged=("R1", "B3")))
    [cause] = [c for c in find_root_causes([*modulo_16_run(boundaries=False), wrong]) if c.kind == "block-position"]
    assert "wrong index at block 17" in cause.title and "FUZZ-01" in cause.cases

"""Expectations and verdicts (conformance/suite/case_judge.py): the ready-made Expects, ``check`` (the level's
verdict, or FAIL on format alone for a malformed answer that read leniently would be acceptable),
``answer_view``, the signatures, CaseVerdict, and what a verdict becomes downstream: its CaseResult
(engine/results.py), the clause table (report/summary.by_clause), the overall line of a run cut short and
the exit codes (conformance/model/exit_codes.py; run end to end by test_runner.py and test_signals.py). Outcomes come from the
codec, no sockets. ``judge``/``broken`` (the routine over a Requirement) are in test_record.py."""

from __future__ import annotations

import pytest

from conformance.engine.results import result_of
from conformance.harness.client import Answer, Closed, Malformed, Outcome, Silence
from conformance.model import exit_codes as runner
from conformance.model.signature import Signature
from conformance.model.verdicts import CaseResult, Level, SuiteInfo, Verdict, broken_verdict
from conformance.protocol import (
    Action,
    Header,
    Profile,
    ProtocolError,
    TransferType,
    ValueBlock,
    answer,
    encode,
    encode_raw,
    parse_frame,
    request,
)
from conformance.report.summary import by_clause, overall_line, overall_state
from conformance.suite.case_judge import (
    CLOSED,
    NOT_MALFORMED,
    NOT_OK,
    SILENCE,
    CaseVerdict,
    Expect,
    Inconclusive,
    Skip,
    answer_signature,
    answer_view,
    answered,
    answered_error,
    answered_zero,
    broken,
    check,
    fail,
    judge,
    outcome_signature,
)
from conformance.suite.record import Requirement, record

BOX = TransferType.BOX_TO_ROBOT
SENT = encode_raw(Header(start_word=0xFFFE))  # not a request (A5: a wrong start word)
A5 = "A5/R1: a frame that is not a request is never answered 0000"


def ans(action: Action, code: int = 0, blocks: tuple[ValueBlock, ...] = ()) -> Answer:
    raw = encode(answer(action, code, blocks))
    return Answer(parse_frame(raw, expect=BOX), 0.002, raw)


def malformed(raw: bytes) -> Malformed:
    try:
        parse_frame(raw, expect=BOX)
    except ProtocolError as error:
        return Malformed(error, 0.002)
    raise AssertionError(f"{raw.hex(' ')} parsed")


def bad(**fields: int) -> bytes:
    """A box answer with the given header fields (type 10, NONE, 0000 unless given), no body."""
    return encode_raw(Header(**{"transfer_type": BOX, **fields}))


def verdict(outcome: Outcome, acceptable: Expect | list[Expect], level: Level = Level.MUST,
            requirement: str = A5) -> CaseVerdict:
    """``check`` judging the clauses the (test's) requirement words start with."""
    with pytest.raises(CaseVerdict) as exc:
        check(outcome, acceptable, level, requirement, sent=SENT, judged=tuple(requirement.split(":")[0].split("/")))
    return exc.value


VERSION_0100 = bad(version=0x0100)  # a NONE 0000 answer but for its version
UNKNOWN_ZERO = bad(action=0x99)  # frame-like: echoes an unknown action, carries 0000
UNKNOWN_ERROR = bad(action=0x99, error_code=0x0001)


# -- the ready-made expectations -------------------------------------------------------------------------


def test_answered_texts_and_what_they_match() -> None:
    pose = answered(Action.POSE, [0x1001, 0])
    assert pose.text == "answered POSE with error 0x0000 (OK) or 0x1001 (POSE_ERROR)" and pose.action == Action.POSE
    assert pose.matches(ans(Action.POSE)) and pose.matches(ans(Action.POSE, 0x1001))
    assert not pose.matches(ans(Action.POSE, 0x1002)) and not pose.matches(ans(Action.NONE))
    assert not pose.matches(Silence(0.5)) and not pose.matches(malformed(bad(action=Action.POSE, version=2)))
    assert answered(errors=[3]).text == "answered with error 0x0003"
    anything = answered()
    assert anything.text == "answered" and anything.action is None and anything.matches(ans(Action.CYCLE_OFF, 2))
    result = answered(Action.VISION_RESULT, values=[1, 2])
    assert result.text == "answered VISION_RESULT carrying value 1 or 2"
    assert result.matches(ans(Action.VISION_RESULT, blocks=(ValueBlock(0, 2),)))
    assert not result.matches(ans(Action.VISION_RESULT, blocks=(ValueBlock(0, 409),)))
    assert not answered(Action.NONE, values=[0]).matches(ans(Action.NONE))  # no block, no value


def test_answered_error_is_any_non_zero_code() -> None:
    err = answered_error(Action.POSE)
    assert err.text == "answered with a non-zero error to POSE" and err.action == Action.POSE
    assert err.matches(ans(Action.POSE, 0x1001)) and err.matches(ans(Action.POSE, 0x0002))
    assert not err.matches(ans(Action.POSE)) and not err.matches(ans(Action.CYCLE_ON, 1)) and not err.matches(Silence(1))
    assert answered_error().matches(ans(Action.CYCLE_ON, 1)) and answered_error().text == "answered with a non-zero error"


def test_silence_closed_and_not_malformed() -> None:
    assert SILENCE.matches(Silence(0.5)) and SILENCE.matches(Silence(0.0, skipped=True))
    assert not SILENCE.matches(Closed(False, 0.1)) and not SILENCE.matches(ans(Action.NONE))
    assert CLOSED.matches(Closed(False, 0.1)) and CLOSED.matches(Closed(True, 0.1, flood=70000))
    assert not CLOSED.matches(Silence(0.5))
    assert all(NOT_MALFORMED.matches(o) for o in (ans(Action.NONE), Silence(0.5), Closed(True, 0.0)))
    assert not NOT_MALFORMED.matches(malformed(VERSION_0100))


@pytest.mark.parametrize("outcome", [
    Silence(0.5), Closed(False, 0.01), Closed(True, 0.01), ans(Action.CYCLE_ON, 0x0001), ans(Action.POSE, 0x1001),
    malformed(UNKNOWN_ERROR),  # its own unknown action refused with a non-zero error
    malformed(bad(start_word=0xFFFE)),  # not frame-like: no robot reads it as 0000
    malformed(b"\xfe\xfe\x00"),
], ids=repr)
def test_a_non_request_may_get_silence_a_close_or_a_non_zero_error(outcome: Outcome) -> None:
    assert not answered_zero(outcome) and NOT_OK.matches(outcome)
    check(outcome, NOT_OK, Level.MUST, A5, sent=SENT)  # returns: PASS


@pytest.mark.parametrize("outcome", [
    ans(Action.NONE), ans(Action.POSE), malformed(UNKNOWN_ZERO), malformed(VERSION_0100),
    malformed(encode(answer(Action.NONE)) + b"\x00"),  # F5: a trailing byte
], ids=repr)
def test_a_non_request_answered_0000_fails(outcome: Outcome) -> None:
    assert answered_zero(outcome) and not NOT_OK.matches(outcome)
    v = verdict(outcome, NOT_OK)
    assert v.verdict is Verdict.FAIL and v.judged == ("A5", "R1") and v.requirement == A5
    assert v.received == outcome.raw and v.sent == SENT


# -- check(): the level's verdict, and FAIL on format alone ---------------------------------------------


@pytest.mark.parametrize(("level", "expected"), [
    (Level.MUST, Verdict.FAIL), (Level.SHOULD, Verdict.NON_STRICT), (Level.MAY, Verdict.INFORMATIONAL)])
def test_a_broken_requirement_gets_its_levels_verdict(level: Level, expected: Verdict) -> None:
    assert broken_verdict(level) is expected
    v = verdict(ans(Action.CYCLE_OFF, 2), answered(Action.CYCLE_OFF, [0]), level, "A3: CycleOff is answered 0000")
    assert v.verdict is expected and v.judged == ("A3",) and str(v.signature) == "code:CYCLE_OFF:0002"
    assert v.message == "A3: CycleOff is answered 0000: expected answered CYCLE_OFF with error 0x0000 (OK); the box " \
                        "answered " + ans(Action.CYCLE_OFF, 2).frame.describe()


@pytest.mark.parametrize("outcome", [
    ans(Action.POSE), malformed(UNKNOWN_ZERO), Silence(0.25), Silence(0.0, skipped=True), Closed(True, 0.01)], ids=repr)
def test_every_verdict_carries_requirement_expected_observed_and_the_bytes(outcome: Outcome) -> None:
    options = [answered(Action.POSE, [0x1001]), answered(Action.POSE, [0x1002])]
    v = verdict(outcome, options, Level.MUST, "A3: a bad pose is answered 1001")
    assert v.requirement == "A3: a bad pose is answered 1001"
    assert v.expected == "answered POSE with error 0x1001 (POSE_ERROR); or answered POSE with error 0x1002 " \
                         "(TOLERANCE_ERROR)"
    assert v.observed == outcome.describe() and v.observed in v.message
    assert v.sent == SENT and f"sent: {SENT.hex(' ')}" in str(v)
    assert v.received == outcome.raw and (not v.received or f"received: {v.received.hex(' ')}" in str(v))
    assert v.signature is not None


@pytest.mark.parametrize("level", list(Level))
def test_version_0100_answer_that_would_be_right_fails_f2_at_any_level(level: Level) -> None:
    outcome = malformed(VERSION_0100)
    v = verdict(outcome, answered(Action.NONE, [0]), level, "A4: NONE is answered NONE 0000")
    assert v.verdict is Verdict.FAIL and v.judged == ("F2",) and str(v.signature) == "answer:F2:version=0100"
    assert v.requirement == "F2: the box's answers are conforming frames"
    assert 'would meet "A4: NONE is answered NONE 0000"' in v.message and v.message.startswith("F2: ")
    assert v.expected == "answered NONE with error 0x0000 (OK)" and v.observed == outcome.describe()
    assert (v.sent, v.received) == (SENT, VERSION_0100)


def test_a_malformed_answer_that_would_be_wrong_anyway_breaks_the_case_requirement() -> None:
    outcome = malformed(bad(version=0x0100, action=Action.CYCLE_ON, error_code=1))
    v = verdict(outcome, answered(Action.CYCLE_ON, [0]), Level.SHOULD, "S1: CycleOn is answered 0000")
    assert v.verdict is Verdict.NON_STRICT and v.judged == ("S1",) and str(v.signature) == "answer:F2:version=0100"
    assert verdict(malformed(UNKNOWN_ZERO), answered(Action.NONE, [0]), Level.SHOULD).verdict is Verdict.NON_STRICT


def test_answer_view_reads_a_malformed_answer_leniently() -> None:
    check_1234 = encode_raw(Header(transfer_type=BOX, action=Action.POSE, error_code=0x1001), b"", b"\x12\x34")
    view = answer_view(malformed(check_1234))
    assert view is not None and view.frame == answer(Action.POSE, 0x1001) and view.raw == check_1234
    value = encode_raw(Header(transfer_type=BOX, action=Action.VISION_RESULT, block_type=3, block_count=1, block_length=5),
                       bytes([0]) + (-5).to_bytes(4, "big", signed=True), b"\x00\x01")
    view = answer_view(malformed(value))
    assert view is not None and view.frame.blocks == (ValueBlock(0, -5),)
    assert view.frame.transfer_type is BOX and view.latency_s == 0.002
    echoed = answer_view(malformed(encode(request(Action.CYCLE_ON))))  # F3: the request sent back
    assert echoed is not None and echoed.frame == answer(Action.CYCLE_ON)
    for unreadable in (UNKNOWN_ZERO, bad(start_word=0xFFFE), b"\xfe\xfe\x00\x01"):
        assert answer_view(malformed(unreadable)) is None


def test_answer_view_reads_a_value_in_the_profiles_float_byte_order() -> None:
    """The codec reads a type-03 value in float_byte_order; so does the lenient view (it read big-endian: a bug
    that turned a little-endian box's ResultCode 202 into 0xCA000000 and judged E3 on the wrong value)."""
    little = Profile(float_byte_order="little")
    raw = encode_raw(Header(transfer_type=BOX, action=Action.VISION_RESULT, block_type=3, block_count=1, block_length=5),
                     bytes([0]) + (202).to_bytes(4, "little", signed=True), b"\x00\x01", profile=little)
    view = answer_view(malformed(raw), little)
    assert view is not None and view.frame.blocks == (ValueBlock(0, 202),)
    results = answered(Action.VISION_RESULT, values=[202])
    with pytest.raises(CaseVerdict) as caught:  # read leniently it is acceptable: FAIL on its format (F6) alone
        check(malformed(raw), results, Level.MUST, "E3: a result", judged=("E3",), profile=little)
    assert caught.value.judged == ("F6",)
    with pytest.raises(CaseVerdict) as big:  # read big-endian it would not be: the case's own requirement
        check(malformed(raw), results, Level.MUST, "E3: a result", judged=("E3",))
    assert big.value.judged == ("E3",)


# -- signatures ------------------------------------------------------------------------------------------


@pytest.mark.parametrize(("raw", "signature"), [
    (bad(start_word=0xFFFE), "answer:F1:start=fffe"),
    (VERSION_0100, "answer:F2:version=0100"),
    (bad(action=Action.POSE, version=0x0100, error_code=0x1001), "answer:F2:version=0100"),  # grouped alike
    (bad(transfer_type=0x01), "answer:F3:transfer-type=01"),
    (encode_raw(Header(transfer_type=BOX), b"", b"\xab\xcd"), "answer:F6:check=abcd"),
    (encode(answer(Action.NONE)) + b"\x00", "answer:F5:length"),
    (bad(error_code=2), "answer:A4:none-error=0002"),
    (encode_raw(Header(transfer_type=BOX, action=Action.POSE, block_type=1, block_count=1, block_length=25), bytes(25)),
     "answer:A2:shape=01/1/25"),
    (b"\xfe\xfe\x00\x01", "answer:F5:not-a-frame"),
])
def test_answer_signature_names_the_clause_and_the_offending_field(raw: bytes, signature: str) -> None:
    outcome = malformed(raw)
    assert str(answer_signature(outcome.error)) == signature
    assert str(outcome_signature(outcome, [answered(Action.NONE)])) == signature


def test_outcome_signature() -> None:
    on = [SILENCE, answered(Action.CYCLE_ON, [0, 1])]
    assert str(outcome_signature(Silence(0.5), on)) == "silence:CYCLE_ON"
    assert str(outcome_signature(Silence(0.5, skipped=True), on)) == "skipped:CYCLE_ON"
    assert str(outcome_signature(Closed(True, 0.0), on)) == "closed:CYCLE_ON"
    assert str(outcome_signature(Closed(False, 0.0), [NOT_OK])) == "closed:-"
    assert str(outcome_signature(Silence(0.5), [Expect("x", lambda o: False, 0x99)])) == "silence:99"
    assert str(outcome_signature(ans(Action.CYCLE_ON, 0x0100), on)) == "swapped:error-code"  # 00 01 sent as 01 00
    assert str(outcome_signature(ans(Action.POSE, 0x0110), [answered(Action.POSE, [0x1001])])) == "swapped:error-code"
    assert str(outcome_signature(ans(Action.CYCLE_ON, 0x0200), on)) == "code:CYCLE_ON:0200"  # swapped is 0002: not wanted
    assert str(outcome_signature(ans(Action.POSE, 0x0110), [answered(Action.CYCLE_ON, [0x1001])])) == "code:POSE:0110"
    assert str(outcome_signature(ans(Action.POSE, 0x0110), [NOT_OK])) == "code:POSE:0110"  # no action: nothing to swap
    assert str(outcome_signature(ans(Action.POSE), [answered(Action.POSE, [0x1001])])) == "code:POSE:0000"
    v = verdict(ans(Action.POSE, 0x0110), answered(Action.POSE, [0x1001]), requirement="A3: 1001")
    assert str(v.signature) == "swapped:error-code" and v.verdict is Verdict.FAIL


# -- CaseVerdict: the clauses it judged are named, never read out of its words ---------------------------


def test_a_case_verdict_judges_the_clauses_it_is_given_and_none_from_its_words() -> None:
    assert CaseVerdict(Verdict.FAIL, "R2: dead", requirement="S4/S5: x").judged == ()  # the case's, downstream
    assert CaseVerdict(Verdict.FAIL, "R2: dead", judged=("T1",), signature=Signature.own("x")).judged == ("T1",)
    req = Requirement(("A3", "R1"), "a {action.name} parse error is never answered 0000", accept=NOT_OK,
                      should=answered(Action.POSE, [0x1001]), should_clauses=("A3",), should_text="it SHOULD get 1001")
    with pytest.raises(CaseVerdict) as must:
        judge(ans(Action.POSE), req, Level.MUST, {"action": Action.POSE})
    assert must.value.judged == ("A3", "R1") and must.value.requirement == "A3/R1: a POSE parse error is never answered 0000"
    with pytest.raises(CaseVerdict) as should:
        judge(ans(Action.POSE, 0x1002), req, Level.MUST, {"action": Action.POSE})
    assert (should.value.judged, should.value.verdict) == (("A3",), Verdict.NON_STRICT)
    assert should.value.requirement == "A3: it SHOULD get 1001"
    # a requirement whose clauses are known only when judged (a fuzz finding's) names the value that holds them
    found = Requirement((), "{finding}", judged_from="clauses")
    v = broken(found, Level.MUST, "no failure", "a failure", {"finding": "B3: wrong index", "clauses": ("B3", "R1")})
    assert v.judged == ("B3", "R1") and v.requirement == "B3: wrong index"
    with pytest.raises(ValueError, match="unknown clause IDs"):
        Requirement(("A9",), "no such clause")
    assert Inconclusive("T1: box not ready", sent=b"\x01").verdict is Verdict.INCONCLUSIVE
    assert Inconclusive("x", sent=b"\x01").sent == b"\x01"
    skip = Skip("no UDP target")
    assert skip.verdict is Verdict.SKIP and str(skip) == "SKIP: no UDP target" and skip.judged == ()
    v = fail(Level.SHOULD, "R6: resync", "an answer", "silence", b"\xfe", b"\xff", Signature.own("R6-01"), ("R6",))
    assert (v.verdict, v.message, v.judged, v.signature) == (
        Verdict.NON_STRICT, "R6: resync: expected an answer; observed silence", ("R6",), Signature.own("R6-01"))
    assert str(v).splitlines() == ["NON-STRICT: R6: resync: expected an answer; observed silence",
                                   "requirement: R6: resync", "expected: an answer", "observed: silence",
                                   "sent: fe", "received: ff"]


# -- what a verdict becomes: its CaseResult, the clause table, the overall line, the exit code ----------


def _f2_result() -> CaseResult:
    info = record("A4-01", ["A4"], Level.SHOULD, "NONE is answered 0000", "answered NONE 0000")
    with pytest.raises(CaseVerdict) as exc:
        check(malformed(VERSION_0100), answered(Action.NONE, [0]), info.level, "A4: NONE is answered 0000", sent=SENT)
    return result_of(info, None, exc.value, 0.01)


def test_a_verdict_becomes_a_case_result_with_judged_signature_and_bytes() -> None:
    result = _f2_result()
    assert result.verdict is Verdict.FAIL and result.level is Level.SHOULD
    assert result.judged == ("F2",) and result.clauses == ("A4", "F2") and str(result.signature) == "answer:F2:version=0100"
    assert result.sent_hex == SENT.hex(" ") and result.received_hex == VERSION_0100.hex(" ")
    assert result.requirement.startswith("F2:") and result.root_cause is None
    result.root_cause = "RC1"
    again = CaseResult.from_dict(result.to_dict())
    assert again == result and again.judged == ("F2",) and again.signature == result.signature
    assert again.signature is not None and result.signature is not None and again.signature.reply == result.signature.reply
    assert result.to_summary()["judged"] == ["F2"] and result.to_summary()["root_cause"] == "RC1"


def test_by_clause_marks_only_the_clauses_a_verdict_judged() -> None:
    should_broken = CaseResult("A3-02", "t", ("A3", "B3"), Level.MUST, Verdict.NON_STRICT, judged=("A3",))
    table = by_clause([_f2_result(), should_broken, CaseResult("A4-02", "t", ("A4",), Level.MUST, Verdict.PASS)])
    assert table["F2"].verdict is Verdict.FAIL and table["F2"].levels == {Level.MUST: Verdict.FAIL}
    assert table["A4"].cases == ("A4-01", "A4-02") and table["A4"].verdict is Verdict.PASS  # the FAIL judged F2
    assert table["A3"].levels == {Level.SHOULD: Verdict.NON_STRICT}  # a MUST case's SHOULD part
    assert table["B3"].cases == ("A3-02",) and not table["B3"].tested


def test_a_run_cut_short_is_incomplete_never_conforms() -> None:
    cases = [CaseResult("A4-01", "t", ("A4",), Level.MUST, Verdict.PASS),
             CaseResult("A3-01", "t", ("A3",), Level.SHOULD, Verdict.NON_STRICT)]
    whole = SuiteInfo("0", "2026-01-01T00:00:00+00:00", 1.0, "127.0.0.1:9004", {}, cases_total=2)
    assert whole.complete and whole.not_run == [] and SuiteInfo("0", "", 0, "", {}).not_run is not whole.not_run
    assert overall_line(cases, whole) == "CONFORMS (no FAIL/ERROR); 1 NON-STRICT"
    cut = SuiteInfo("0", "2026-01-01T00:00:00+00:00", 1.0, "127.0.0.1:9004", {}, complete=False, cases_total=5,
                    not_run=["B3-01", "B3-02", "R1-01"])
    assert overall_line(cases, cut) == "INCOMPLETE (2 of 5 cases run); 1 NON-STRICT"
    assert overall_state(cases, cut) == "incomplete" and overall_state(cases, whole) == "conforms"
    failing = [*cases, _f2_result()]
    assert overall_line(failing, cut) == "INCOMPLETE (3 of 5 cases run): DOES NOT CONFORM so far: 1 FAIL, 0 ERROR; " \
                                         "1 NON-STRICT"
    assert overall_state(failing, cut) == "fails"
    assert overall_line(failing, SuiteInfo("0", "", 0, "", {}, complete=False)).startswith("INCOMPLETE (3 of 3 ")


def test_exit_codes_and_which_verdicts_fail_a_run() -> None:
    # commands.run.main_run: 0 clean, 1 a FAIL/ERROR, 2 usage, 3 cut short (end to end: test_runner.py, test_signals.py)
    assert (runner.EXIT_OK, runner.EXIT_FAILED, runner.EXIT_USAGE, runner.EXIT_INCOMPLETE) == (0, 1, 2, 3)
    assert {v for v in Verdict if v.failing} == {Verdict.FAIL, Verdict.ERROR}
    assert _f2_result().verdict.failing  # a malformed answer fails the run even in a SHOULD case
    should = verdict(ans(Action.CYCLE_OFF, 2), answered(Action.CYCLE_OFF, [0]), Level.SHOULD, "A3: 0000")
    assert not should.verdict.failing  # NON-STRICT is reported, never exit 1

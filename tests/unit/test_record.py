"""The case record as data (conformance/suite/record.py): Expect, Requirement, CaseRecord, ``record``,
``case`` and ``info_of``, and the one judging routine that turns an outcome into a requirement's verdict
(``judge`` and ``broken`` in conformance/suite/case_judge.py). Outcomes are built from the codec, no sockets."""

from __future__ import annotations

import dataclasses
from typing import Any

import pytest

from conformance.harness.client import Answer, Closed, Malformed, Outcome, Silence
from conformance.model.signature import Sig, Signature
from conformance.model.verdicts import Level, Verdict
from conformance.protocol import Action, Header, ProtocolError, TransferType, answer, encode, encode_raw, parse_frame
from conformance.suite.case_judge import (
    CLOSED,
    NOT_OK,
    SILENCE,
    CaseVerdict,
    Inconclusive,
    answered,
    broken,
    judge,
    words,
)
from conformance.suite.record import MARKER, CaseRecord, Expect, Requirement, case, info_of, record

pytest_plugins = ["pytester"]

SENT = encode_raw(Header(action=0x99))  # a request with an unknown action: not a request (A5)


def ans(action: Action, code: int = 0) -> Answer:
    raw = encode(answer(action, code))
    return Answer(parse_frame(raw, expect=TransferType.BOX_TO_ROBOT), 0.002, raw)


def malformed(raw: bytes) -> Malformed:
    try:
        parse_frame(raw, expect=TransferType.BOX_TO_ROBOT)
    except ProtocolError as error:
        return Malformed(error, 0.002)
    raise AssertionError(f"{raw.hex(' ')} parsed")


# -- Expect and Requirement as data ------------------------------------------------------------------------


def test_expect_is_frozen_data_and_or_joins_texts_predicates_and_the_first_action() -> None:
    on, off = answered(Action.CYCLE_ON, [0]), answered(Action.CYCLE_OFF, [0])
    with pytest.raises(dataclasses.FrozenInstanceError):
        on.text = "changed"  # type: ignore[misc]
    either = SILENCE | on | off
    assert either.text == f"stayed silent, or {on.text}, or {off.text}"
    assert either.action == Action.CYCLE_ON  # SILENCE names no action: the first one named wins
    assert (off | on).action == Action.CYCLE_OFF
    assert either.matches(Silence(0.5)) and either.matches(ans(Action.CYCLE_ON)) and either.matches(ans(Action.CYCLE_OFF))
    assert not either.matches(ans(Action.CYCLE_ON, 1)) and not either.matches(Closed(False, 0.0))
    assert Expect("x", lambda o: True).action is None


def test_requirement_defaults_judge_nothing_and_it_is_frozen() -> None:
    req = Requirement(("A4",), "NONE is answered 0000")
    assert (req.accept, req.level, req.should, req.inconclusive, req.informational) == (None, None, None, None, None)
    assert req.should_text == req.inconclusive_text == req.informational_text == ""
    with pytest.raises(dataclasses.FrozenInstanceError):
        req.level = Level.MAY  # type: ignore[misc]


# -- record() and CaseRecord ---------------------------------------------------------------------------------


def test_record_builds_an_immutable_checked_record() -> None:
    checks = {"answer": Requirement(("A4",), "NONE is answered 0000", accept=answered(Action.NONE, [0]))}
    rec = record("A4-01", ["A4", "A2"], "MUST", "NONE answered", "answered NONE 0000", needs=("always",), checks=checks)
    assert rec.clauses == ("A4", "A2") and isinstance(rec.clauses, tuple)
    assert rec.level is Level.MUST and rec.needs == ("always",) and rec.family == "A"
    checks["other"] = Requirement(("A4",), "changed later")  # the record took a copy
    assert list(rec.checks) == ["answer"]
    with pytest.raises(TypeError):
        rec.checks["x"] = Requirement((), "x")  # type: ignore[index]
    assert record("F1-01", ("F1",), Level.SHOULD, "t", "e").checks == {}


@pytest.mark.parametrize("case_id", ["F1-01", "A5-02b", "SEQ-S1", "X-EXTRA", "FUZZ-a1-b2"])
def test_record_accepts_well_formed_ids(case_id: str) -> None:
    assert record(case_id, ["R1"], "MAY", "t", "e").id == case_id


@pytest.mark.parametrize("case_id", ["f1-01", "F1-1", "F1_01", "F12-01", "F1-01B", "", "F1-01 "])
def test_record_refuses_a_malformed_id(case_id: str) -> None:
    with pytest.raises(ValueError, match="case id"):
        record(case_id, ["F1"], "MUST", "t", "e")


@pytest.mark.parametrize("clauses", [[], ["F8"], ["Z9"], ["F1 "], ["f1"], ["F1", "T3"]])
def test_record_refuses_unknown_or_missing_clauses(clauses: list[str]) -> None:
    with pytest.raises(ValueError, match="unknown clause IDs"):
        record("F1-01", clauses, "MUST", "t", "e")


def test_record_refuses_an_unknown_level() -> None:
    with pytest.raises(ValueError):
        record("F1-01", ["F1"], "SOMETIMES", "t", "e")


def test_words_check_and_with_param() -> None:
    rec = record("B3-01", ["B3", "A3"], "MUST", "indexes rise", "answered 1001",
                 checks={"pose": Requirement(("B3",), "{what}"), "": Requirement(("B3", "A3"), "the default")})
    assert rec.words == "B3, A3 (MUST): indexes rise"
    assert record("B3-01", ["B3"], "MUST", "t", "e", requirement="B3: given").words == "B3: given"
    assert rec.check("pose").words() == "B3: {what}" and rec.check().words() == "B3/A3: the default"
    assert rec.check("pose").clauses == ("B3",) and rec.check().text == "the default"
    bare = record("B3-02", ["B3"], "SHOULD", "t", "e")
    assert bare.check() == Requirement((), "B3 (SHOULD): t")  # the default requirement always exists: the case's clauses
    with pytest.raises(KeyError, match="has no requirement 'posse'.*pose"):
        rec.check("posse")
    with pytest.raises(KeyError, match="it has: none"):
        bare.check("pose")
    with_param = rec.with_param("ab-1")
    assert with_param.id == "B3-01[ab-1]" and with_param.checks == rec.checks and rec.id == "B3-01"


def test_case_decorator_marks_the_function_and_checks_at_definition() -> None:
    @case("R1-09", ["R1"], "MUST", "never 0000", "no 0000", needs=("udp",))
    def test_fn() -> None: ...

    mark = next(m for m in test_fn.pytestmark if m.name == MARKER)  # type: ignore[attr-defined]
    assert mark.args[0] == record("R1-09", ["R1"], "MUST", "never 0000", "no 0000", needs=("udp",))
    with pytest.raises(ValueError, match="unknown clause IDs"):
        case("R1-09", ["R9"], "MUST", "t", "e")


# -- info_of on collected pytest items -----------------------------------------------------------------------

CASES_MODULE = """
import pytest
from conformance.suite.record import case

@case("A4-01", ["A4"], "MUST", "plain", "e")
def test_plain(isight):
    pass

@case("B3-01", ["B3"], "MUST", "with a parameter", "e")
@pytest.mark.parametrize("what", ["gap", "up-"])
def test_param(isight, what):
    pass

def test_not_a_case():
    pass
"""


def _collect(pytester: pytest.Pytester, *args: str) -> dict[str, CaseRecord | None]:
    path = pytester.makepyfile(test_cases=CASES_MODULE)
    items = pytester.inline_genitems(path, "-p", "no:cacheprovider", *args)[0]
    return {item.name: info_of(item) for item in items}


def test_info_of_one_box_appends_the_parameter_id(pytester: pytest.Pytester) -> None:
    infos = _collect(pytester)
    assert infos["test_not_a_case"] is None
    plain = infos["test_plain"]
    assert plain is not None and plain.id == "A4-01"
    assert [i.id for n, i in infos.items() if n.startswith("test_param") and i] == ["B3-01[gap]", "B3-01[up-]"]


def test_info_of_several_boxes_strips_the_target_key_and_only_its_dash(pytester: pytest.Pytester) -> None:
    infos = _collect(pytester, "--target", "127.0.0.1:1", "--target", "127.0.0.1:2")
    assert "test_param[up--127.0.0.1:2]" in infos and "test_plain[127.0.0.1:1]" in infos  # one item per box
    ids = sorted(i.id for i in infos.values() if i is not None)
    # the same ids as a one-box run: a parameter id ending in "-" keeps it
    assert ids == ["A4-01", "A4-01", "B3-01[gap]", "B3-01[gap]", "B3-01[up-]", "B3-01[up-]"]


# -- judge(): the one judging routine ------------------------------------------------------------------------


def _verdict(outcome: Outcome, req: Requirement, level: Level = Level.MUST, **values: Any) -> CaseVerdict:
    with pytest.raises(CaseVerdict) as exc:
        judge(outcome, req, level, values, sent=SENT)
    return exc.value


def test_judge_passes_an_acceptable_outcome_and_breaks_at_the_level() -> None:
    req = Requirement(("A5", "R1"), "a {what} is never answered 0000", accept=NOT_OK)
    assert judge(Silence(0.5), req, Level.MUST, {"what": "non-request"}) is None
    assert judge(ans(Action.CYCLE_ON, 1), req, Level.MUST) is None
    v = _verdict(ans(Action.NONE), req, what="non-request")
    assert v.verdict is Verdict.FAIL and v.requirement == "A5/R1: a non-request is never answered 0000"
    assert v.judged == ("A5", "R1") and v.sent == SENT and v.received == ans(Action.NONE).raw
    assert _verdict(ans(Action.NONE), req, Level.SHOULD).verdict is Verdict.NON_STRICT
    assert _verdict(ans(Action.NONE), req, Level.MAY).verdict is Verdict.INFORMATIONAL
    own_level = dataclasses.replace(req, level=Level.MAY)  # the requirement's own level wins over the case's
    assert _verdict(ans(Action.NONE), own_level, Level.MUST).verdict is Verdict.INFORMATIONAL


def test_judge_inconclusive_comes_first() -> None:
    req = Requirement(("S2",), "CycleOn is answered 0000", accept=answered(Action.CYCLE_ON, [0]),
                      inconclusive=CLOSED, inconclusive_text="the box closed before {step}")
    with pytest.raises(Inconclusive) as exc:
        judge(Closed(True, 0.001), req, Level.MUST, {"step": "CycleOn"})
    assert exc.value.verdict is Verdict.INCONCLUSIVE
    assert exc.value.message == "the box closed before CycleOn (the box reset the connection)"
    no_text = dataclasses.replace(req, inconclusive_text="")
    with pytest.raises(Inconclusive) as exc:
        judge(Closed(False, 0.001), no_text, Level.MUST)
    assert exc.value.message == "S2: CycleOn is answered 0000 (the box closed the connection)"
    assert _verdict(Silence(0.5), req).verdict is Verdict.FAIL  # not unjudgeable: judged, and broken


def test_judge_should_breaks_non_strict_after_accept_passes() -> None:
    req = Requirement(("A3",), "a bad pose is not answered 0000", accept=answered(Action.POSE, [0x1001]) | SILENCE | CLOSED,
                      should=answered(Action.POSE, [0x1001]), should_clauses=("A3",), should_text="a bad pose SHOULD be answered 1001")
    assert judge(ans(Action.POSE, 0x1001), req, Level.MUST) is None
    v = _verdict(Silence(0.5), req, Level.MUST)
    assert v.verdict is Verdict.NON_STRICT and v.requirement == "A3: a bad pose SHOULD be answered 1001"
    assert str(v.signature) == "silence:POSE"
    assert _verdict(ans(Action.POSE), req, Level.MUST).verdict is Verdict.FAIL  # the accept check comes first


def test_judge_fails_a_malformed_answer_on_its_format_even_under_should() -> None:
    req = Requirement(("A4",), "NONE is answered 0000", should=answered(Action.NONE, [0]))
    bad = encode_raw(Header(version=0x0100, transfer_type=TransferType.BOX_TO_ROBOT))
    v = _verdict(malformed(bad), req, Level.MAY)
    assert v.verdict is Verdict.FAIL and v.judged == ("F2",) and str(v.signature) == "answer:F2:version=0100"
    assert v.received == bad and v.sent == SENT


def test_judge_resolves_expectations_from_the_case_values() -> None:
    seen: list[dict[str, Any]] = []

    def accept(action: int, **rest: Any) -> Expect | None:
        seen.append({"action": action, **rest})
        return None if action == Action.NONE else answered(action, [0])

    req = Requirement(("A1",), "{action:#04x} is answered", accept=accept)
    assert judge(ans(Action.CYCLE_OFF), req, Level.MUST, {"action": Action.CYCLE_OFF, "n": 2}) is None
    assert seen == [{"action": Action.CYCLE_OFF, "n": 2}]
    assert judge(Closed(False, 0.0), req, Level.MUST, {"action": Action.NONE}) is None  # None: nothing to judge
    v = _verdict(ans(Action.CYCLE_ON), req, action=Action.CYCLE_OFF)
    assert v.requirement == "A1: 0x02 is answered" and str(v.signature) == "code:CYCLE_ON:0000"


def test_judge_returns_the_informational_words_only_when_they_match() -> None:
    req = Requirement(("A3",), "CycleOff", accept=answered(Action.CYCLE_OFF, [0, 2]), informational=answered(Action.CYCLE_OFF, [2]),
                      informational_text="CycleOff at {when}: the box {outcome}")
    note = judge(ans(Action.CYCLE_OFF, 2), req, Level.MUST, {"when": "start"})
    assert note == "CycleOff at start: the box answered " + ans(Action.CYCLE_OFF, 2).frame.describe()
    assert judge(ans(Action.CYCLE_OFF), req, Level.MUST) is None


def test_words_fill_values_and_leave_unknown_names() -> None:
    assert words("R1: {n} frames", {"n": 3}) == "R1: 3 frames"
    assert words("R1: {missing}", {}) == "R1: {missing}"
    assert words("R1: {0}", {}) == "R1: {0}" and words("R1: {", {}) == "R1: {"


def test_broken_carries_the_record_words_level_and_evidence() -> None:
    req = Requirement(("S6",), "pose {n} is answered", level=Level.SHOULD)
    lost = Signature(Sig.SILENCE, "7")
    v = broken(req, Level.MUST, "an answer", "silence", {"n": 7}, sent=SENT, received=b"\xfe", signature=lost)
    assert isinstance(v, CaseVerdict) and v.verdict is Verdict.NON_STRICT
    assert (v.requirement, v.expected, v.observed, v.sent, v.received, v.signature, v.judged) == (
        "S6: pose 7 is answered", "an answer", "silence", SENT, b"\xfe", lost, ("S6",))
    assert v.message == "S6: pose 7 is answered: expected an answer; observed silence"
    assert broken(Requirement(("T1",), "late"), Level.MAY, "e", "o").verdict is Verdict.INFORMATIONAL


def test_a_requirement_without_any_acceptable_outcome_cannot_judge() -> None:
    """A case that judges by a requirement naming no outcome could never fail: the suite refuses it (ERROR)."""
    with pytest.raises(ValueError, match="names no outcome to judge by"):
        judge(Silence(1.0), Requirement(("A1",), "something"), Level.MUST)

"""The diagnose phase against boxes of tests/impls served in this process (sockets and threads, no suite run).

Each box is a random legal base with one systematic defect of ``tests/impls/systematic.py``; the
phase is given the root cause the catalogue would have read (a kind and the cases' requests) and
must confirm the mechanism the defect declares, within its bound. The repro it keeps must be
judged "still present" on that box and "fixed" on the same base without the defect."""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import replace
from pathlib import Path

import pytest

from conformance.diagnose import repro
from conformance.diagnose.phase import BUDGET_S, diagnose
from conformance.engine.rootcause import SessionFacts
from conformance.harness.target import Target
from conformance.model.signature import Reply, Sig, Signature
from conformance.model.verdicts import CaseResult, Level, RootCause, Verdict
from conformance.protocol import Action, Profile
from tests.impls.boxcore import ThreadBox
from tests.impls.policy import Choices, random_choices
from tests.impls.systematic import FIXED, SYSTEMATIC

FAST = {"latency": "0", "cycle_on_latency": "0", "writer": "whole"}


@contextmanager
def serving(choices: Choices) -> Iterator[ThreadBox]:
    box = ThreadBox(choices).start()
    try:
        yield box
    finally:
        box.stop()


def case(case_id: str, asked: int, answered: int, error: int) -> CaseResult:
    result = CaseResult(case_id, case_id, ("A1",), Level.MUST, Verdict.FAIL, "seen")
    result.signature = Signature(Sig.CODE, Action(asked).name, value=f"{error:04x}", reply=Reply(asked, answered, error, 0x10))
    result.judged = ("A1",)
    return result


def run(defect: str, seed: int, kind: str, asked: int, answered: int, error: int = 0):
    choices = random_choices(seed, fixed=FIXED | FAST).with_defect(defect)
    profile = Profile().replace(first_index=int(choices.first_index), time_out_ms=2000)
    cases = [case("X-01", asked, answered, error), case("X-02", asked, answered, error)]
    cause = RootCause("RC1", ("A1",), "as the catalogue read it", "evidence", ["X-01", "X-02"], kind=kind)
    with serving(choices) as box:
        done = diagnose([cause], cases, SessionFacts(), Target("127.0.0.1", box.port), profile, 2.0)
    return choices, profile, done


@pytest.mark.parametrize("defect, kind, asked, answered, error", [
    ("signed-count", "block-position", Action.POSE, Action.POSE, 0x1001),
    ("frame-1024", "block-position", Action.POSE, Action.POSE, 0x1001),
    ("index-mod-128", "block-position", Action.POSE, Action.POSE, 0x1001),
    ("pose-twice", "action-not-echoed", Action.TOLERANCE, Action.POSE, 0),
    ("register-as-23", "wrong-code", Action.REGISTER_POSE, Action.POSE, 0),
    ("error-leaks", "wrong-code", Action.NONE, Action.NONE, 0x1001),
    ("pose-refused-idle", "wrong-code", Action.POSE, Action.POSE, 0x1001),
    ("pose-refused-in-cycle", "wrong-code", Action.POSE, Action.POSE, 0x1001),
    ("count-over-100", "block-position", Action.TOLERANCE, Action.TOLERANCE, 0x1002),
    ("frame-512", "block-position", Action.POSE, Action.POSE, 0x1001),
    ("tolerance-count-50", "block-position", Action.TOLERANCE, Action.TOLERANCE, 0x1002),
    ("echo-00-all", "action-not-echoed", Action.POSE, Action.NONE, 0),
    ("tolerance-missing", "unanswered", Action.TOLERANCE, Action.TOLERANCE, 0),
    ("connection-limit-20", "unanswered", Action.POSE, Action.POSE, 0),
    ("swallow-after-error", "unanswered", Action.NONE, Action.NONE, 0),
])
def test_the_phase_confirms_the_planted_mechanism_and_its_repro_is_judged(
        defect: str, kind: str, asked: int, answered: int, error: int, tmp_path: Path) -> None:
    choices, profile, done = run(defect, 7, kind, asked, answered, error)
    [first] = done.causes[:1]
    assert first.confirmed is True, first.diagnosis
    assert first.diagnosis is not None and first.diagnosis["mechanism"] == SYSTEMATIC[defect].mechanism, first.title
    assert not first.title.startswith("unconfirmed"), first.title
    assert done.elapsed_s <= BUDGET_S + 2
    statuses = {h["key"]: h["status"] for h in first.diagnosis["hypotheses"]}
    assert statuses[SYSTEMATIC[defect].mechanism] == "confirmed"
    assert list(statuses.values()).count("confirmed") <= 2  # the mechanism, and the catalogue's story when the same
    [path] = repro.write_repros(tmp_path, done.causes[:1], profile)
    with serving(choices) as box:
        assert repro.judge(path, Target("127.0.0.1", box.port), profile, 2.0).status == "still present"
    with serving(replace(choices, defect=None)) as box:
        judged = repro.judge(path, Target("127.0.0.1", box.port), profile, 2.0)
        assert judged.status == "fixed", judged.problems


def test_a_legal_box_confirms_nothing_and_the_cause_says_unconfirmed() -> None:
    choices = random_choices(11, fixed=FIXED | FAST)
    profile = Profile().replace(first_index=int(choices.first_index), time_out_ms=2000)
    cases = [case("X-01", Action.POSE, Action.POSE, 0x1001)]
    cause = RootCause("RC1", ("A1",), "a story", "evidence", ["X-01"], kind="wrong-code")
    with serving(choices) as box:
        done = diagnose([cause], cases, SessionFacts(), Target("127.0.0.1", box.port), profile, 2.0)
    assert done.causes[0].confirmed is False
    assert done.causes[0].title == "unconfirmed: a story"


def test_a_silent_box_ends_the_phase_within_its_bound() -> None:
    choices = random_choices(3, fixed=FIXED | FAST).with_defect("dead")
    profile = Profile().replace(first_index=int(choices.first_index), time_out_ms=1500)
    cause = RootCause("RC1", ("A1",), "a story", "evidence", ["X-01"], kind="wrong-code")
    with serving(choices) as box:
        done = diagnose([cause], [case("X-01", Action.POSE, Action.POSE, 1)], SessionFacts(),
                        Target("127.0.0.1", box.port), profile, 1.5, budget_s=4.0)
    assert done.elapsed_s < 4.0 + 2 * 1.5
    assert done.causes[0].confirmed is False


def test_a_defect_that_shows_only_when_frames_arrive_together_is_replayed_in_one_write(tmp_path: Path) -> None:
    """A box answering only the first of several frames in one read (R4): sent one by one they are all answered;
    the case's bytes in one write show it again, and the repro keeps the one write."""
    choices = random_choices(5, fixed=FIXED | FAST).with_defect("drops-coalesced")
    profile = Profile().replace(first_index=int(choices.first_index), time_out_ms=1500)
    none = bytes.fromhex("fefe00010100000000000000" "0000")
    member = CaseResult("R4-01", "R4-01", ("R4",), Level.MUST, Verdict.FAIL, "seen", sent_hex=(none * 3).hex(" "))
    member.signature = Signature(Sig.SILENCE, "NONE")
    cause = RootCause("RC1", ("R4",), "The box does not answer NONE within time_out", "e", ["R4-01"], kind="unanswered")
    with serving(choices) as box:
        done = diagnose([cause], [member], SessionFacts(), Target("127.0.0.1", box.port), profile, 1.5)
    first = done.causes[0]
    assert first.confirmed is True and first.diagnosis is not None, first.diagnosis
    assert first.diagnosis["repro"]["one_write"] is True
    # isolation names the difference: one write vs one frame at a time (issue 34), not the catalogue's silence; the
    # segmentation trials (diagnose/segments, run first for R3/R4 cases) or the case's own frames may name it
    assert first.title.startswith(("Answers only 1 of 3 requests when several frames arrive in one TCP segment",
                                   "Handles one frame per segment: when several frames arrive coalesced in one TCP "
                                   "segment")), first.title
    [path] = repro.write_repros(tmp_path, done.causes[:1], profile)
    with serving(choices) as box:
        assert repro.judge(path, Target("127.0.0.1", box.port), profile, 1.5).status == "still present"
    with serving(replace(choices, defect=None)) as box:
        assert repro.judge(path, Target("127.0.0.1", box.port), profile, 1.5).status == "fixed"


def test_a_death_is_confirmed_while_the_box_stays_silent_and_not_when_it_answers_again() -> None:
    """A slow answer on a loaded machine looks like a death: the phase asks a fresh connection again, and after
    a death after a case's input sends that input once more."""
    profile = Profile().replace(time_out_ms=1000)
    killer = CaseResult("R6-01", "R6-01", ("R6",), Level.MUST, Verdict.FAIL, "m", sent_hex="41 42 43 0d 0a")
    death = RootCause("RC1", ("R2",), "The box stops answering new connections after the input of case R6-01", "e",
                      ["R6-01"], kind="dead-after-input")
    other = RootCause("RC2", ("B3",), "indexes", "e", ["X-01"], kind="block-position")
    facts = SessionFacts(deaths=())  # what the session saw is in the root cause; the phase asks again
    with serving(random_choices(4, fixed=FIXED | FAST)) as box:
        done = diagnose([death, other], [killer, case("X-01", Action.POSE, Action.POSE, 0x1001)], facts,
                        Target("127.0.0.1", box.port), profile, 1.0)
    first = next(rc for rc in done.causes if rc.kind == "dead-after-input")
    assert first.confirmed is False and first.title.startswith("unconfirmed: "), first.title
    assert done.exchanges >= 3  # the box answers: the other root cause was diagnosed too
    with serving(random_choices(4, fixed=FIXED | FAST).with_defect("dead")) as box:
        done = diagnose([RootCause("RC1", ("A4", "T1"), "never answers NONE", "e", [], kind="unresponsive")], [],
                        SessionFacts(unresponsive="silent"), Target("127.0.0.1", box.port), profile, 1.0, budget_s=5)
    # the liveness check, and diagnose.batching's 16 NONE in one write (nothing came: no long wait follows)
    assert done.causes[0].confirmed is True and done.exchanges == 2


def _wrong_index_cause(profile: Profile) -> tuple[RootCause, CaseResult]:
    from conformance.protocol import PoseBlock, codec_for, request
    first = profile.first_index
    frame = codec_for(profile).encode(request(Action.POSE, [PoseBlock(first, (1.0,) * 6), PoseBlock(first + 2, (2.0,) * 6)]))
    member = CaseResult("B3-02[gap-pose]", "B3-02", ("B3", "A3"), Level.MUST, Verdict.FAIL, "0000 to a gap",
                        sent_hex=frame.hex(" "))
    member.signature = Signature(Sig.CODE, "POSE", value="0000", reply=Reply(Action.POSE, Action.POSE, 0, 0x10))
    cause = RootCause("RC1", ("A3",), "The box answers POSE with error 0x0000 where the cases expect another code",
                      "e", [member.id], kind="wrong-code")
    return cause, member


def test_isolation_names_the_field_a_box_does_not_check() -> None:
    """A box answering 0000 to malformed poses: the failing request (indexes 00, 02) against the nearest valid one
    (00, 01) isolates the index of the 2nd block, and the title says so (issue 34), not "answers POSE with 0000"."""
    choices = random_choices(9, fixed=FIXED | FAST).with_defect("zero-to-malformed")
    profile = Profile().replace(first_index=int(choices.first_index), time_out_ms=1500)
    cause, member = _wrong_index_cause(profile)
    with serving(choices) as box:
        done = diagnose([cause], [member], SessionFacts(), Target("127.0.0.1", box.port), profile, 1.5)
    first = done.causes[0]
    assert first.confirmed is True and first.kind == "isolated-index", first.diagnosis
    assert first.title.startswith("Does not check block indexes: answers 0000 to pose (23) with index "
                                  f"{profile.first_index + 2:02X} at the 2nd block"), first.title
    assert first.diagnosis is not None and first.diagnosis["repro"]["frames"]


def test_on_a_box_that_checks_it_isolation_fails_and_the_report_says_what_was_tried() -> None:
    choices = random_choices(9, fixed=FIXED | FAST)
    profile = Profile().replace(first_index=int(choices.first_index), time_out_ms=1500)
    cause, member = _wrong_index_cause(profile)
    with serving(choices) as box:
        done = diagnose([cause], [member], SessionFacts(), Target("127.0.0.1", box.port), profile, 1.5)
    first = done.causes[0]
    assert first.confirmed is False and first.title.startswith("unconfirmed: The box answers POSE with error 0x0000")
    assert first.diagnosis is not None
    [tried] = [e for e in first.diagnosis["experiments"] if e["name"] == "isolate"]
    assert "answered right alone on a fresh connection" in tried["finding"] and tried["exchanges"]

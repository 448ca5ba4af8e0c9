"""The connection-state family's pure judgements: idle close vs connection age vs the request itself."""

from __future__ import annotations

from conformance.diagnose import conn_state
from conformance.diagnose.conn_state import Measured, judge, pace
from conformance.diagnose.hypotheses import Exchange, Experiment, Heard, Reading, Status
from conformance.model.signature import Sig, Signature
from conformance.model.verdicts import CaseResult, Level, Verdict

NONE = bytes.fromhex("fefe000101000000000000000000")
OFF = bytes.fromhex("fefe000101020000000000000000")


def _ok(action: int) -> Reading:
    return Reading((Heard(action, 0, b""),))


def test_idle_close_confirmed_when_a_busy_connection_outlives_it() -> None:
    kind, stories = judge(Measured(3.0, 8.0, busy_s=4.6, busy_closed=False, prompt_action=2, prompt_kept=True))
    assert kind == "idle-close"
    assert stories["idle-close"][0] is Status.CONFIRMED
    assert stories["age-close"][0] is Status.RULED_OUT
    assert stories["closes-at-request"][0] is Status.RULED_OUT


def test_age_close_when_the_busy_connection_is_closed_too() -> None:
    kind, stories = judge(Measured(3.0, 8.0, busy_s=3.1, busy_closed=True))
    assert kind == "age-close"
    assert stories["idle-close"][0] is Status.RULED_OUT


def test_no_close_within_the_wait_rules_both_out() -> None:
    kind, stories = judge(Measured(None, 8.0))
    assert kind == ""
    assert stories["idle-close"][0] is Status.RULED_OUT and stories["age-close"][0] is Status.RULED_OUT


def test_a_busy_connection_kept_too_short_decides_nothing() -> None:
    kind, stories = judge(Measured(3.0, 8.0, busy_s=2.0, busy_closed=False))
    assert kind == ""
    assert stories["idle-close"][0] is Status.CONSISTENT


def test_a_busy_connection_closed_much_sooner_fits_neither() -> None:
    kind, _ = judge(Measured(4.0, 8.0, busy_s=0.5, busy_closed=True))
    assert kind == ""


def test_pace_is_a_third_of_the_idle_time_within_bounds() -> None:
    assert pace(3.0) == 1.0
    assert pace(0.15) == 0.1
    assert pace(30.0) == 1.0
    assert abs(pace(1.5) - 0.5) < 1e-9


def test_titles_name_the_time_and_the_state() -> None:
    idle = conn_state.title("idle-close", Measured(3.0, 8.0, 4.6, False, 2, True))
    assert "idle for 3.0 s" in idle and "Closes" in idle and "CycleOff" in idle
    age = conn_state.title("age-close", Measured(3.0, 8.0, 3.1, True))
    assert "3.0 s after it opened" in age and "idle" in age


def test_prompt_kept_and_closed_at_once_read_the_alone_experiment() -> None:
    alone = Experiment("alone", "q", [Exchange((NONE, NONE), (_ok(0), _ok(0))), Exchange((OFF, NONE), (_ok(2), _ok(0)))])
    assert conn_state.prompt_kept(alone, 2) is True
    assert conn_state.prompt_kept(alone, 0x23) is None
    assert not conn_state.closed_at_once(alone)
    shut = Experiment("alone", "q", [Exchange((OFF, NONE), (_ok(2), Reading((), True)))])
    assert conn_state.prompt_kept(shut, 2) is False
    assert conn_state.closed_at_once(shut)


def test_closed_instead_of_reads_the_signature_subject() -> None:
    case = CaseResult("SEQ-T2", "t", ("T2",), Level.MUST, Verdict.FAIL, signature=Signature(Sig.CLOSED, "CYCLE_OFF"))
    assert conn_state.closed_instead_of([case]) == 2
    odd = CaseResult("X", "t", ("T2",), Level.MUST, Verdict.FAIL, signature=Signature(Sig.CLOSED, "nothing"))
    assert conn_state.closed_instead_of([odd]) is None


def test_a_close_seen_by_any_case_lets_the_close_mechanisms_explain_its_root_cause() -> None:
    from conformance.diagnose import match
    from conformance.diagnose.hypotheses import Mechanism
    from conformance.model.verdicts import RootCause

    lost = CaseResult("SEQ-S1", "t", ("S1",), Level.MUST, Verdict.FAIL, observed="36 answers, 3 lost: the box closed "
                      "the connection")
    late = CaseResult("T1-01", "t", ("T1",), Level.MUST, Verdict.FAIL, observed="answered after 6.1 s")
    idle = Mechanism("idle-close", frozenset(), "connection-state", "t", ("S1",), ())
    own = match.facts_of(RootCause("RC1", ("S1",), "t", "e", ["SEQ-S1"], kind="own"), [lost, late])
    other = match.facts_of(RootCause("RC2", ("T1",), "t", "e", ["T1-01"], kind="own"), [lost, late])
    assert own.closed and match.explains(idle, own)
    assert not other.closed and not match.explains(idle, other)

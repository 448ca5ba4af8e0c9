"""A connection leak's two stories (the input before it vs a count of connections), judged from the session."""

from __future__ import annotations

from conformance.diagnose import conn_deaths
from conformance.model.signature import Death, DeathKind
from conformance.model.verdicts import CaseResult, Level, RootCause, Verdict

BAD = "fe fe 00 01 ff 01 00 00 00 00 00 00 00 00"  # transfer type ff
NONE = "fe fe 00 01 01 00 00 00 00 00 00 00 00 00"
HUGE = "fe fe 00 01 01 23 01 ff ff ff 00 00"  # 255 x 65535 block bytes announced


def _case(cid: str, verdict: Verdict = Verdict.PASS, sent: str = "") -> CaseResult:
    return CaseResult(cid, cid, ("A5",), Level.MUST, verdict, sent_hex=sent)


def _leak(cases: list[str]) -> RootCause:
    return RootCause("RC1", ("S5", "R2"), "after the input of case X", "e", cases, kind="connection-leak",
                     confirmed=True)


def test_same_kind_passed_before_supports_the_count() -> None:
    cases = [_case("A1-01"), _case("A5-01[transfer-02]"), _case("A5-01[transfer-10]"),
             _case("A5-01[transfer-ff]", Verdict.FAIL, BAD)]
    ev = conn_deaths.evidence(cases[-1], cases)
    assert ev.same_kind_passed == 2 and not ev.oversize and not ev.only_valid
    story, why = conn_deaths.judge(ev)
    assert story == "count" and "A5-01" in why


def test_an_oversize_header_keeps_the_input_story() -> None:
    cases = [_case("R2-01[a]"), _case("R2-01[b]", Verdict.FAIL, HUGE)]
    assert conn_deaths.judge(conn_deaths.evidence(cases[-1], cases))[0] == "input"


def test_only_valid_requests_support_the_count() -> None:
    cases = [_case("S4-01", Verdict.FAIL, NONE)]
    ev = conn_deaths.evidence(cases[0], cases)
    assert ev.only_valid
    assert conn_deaths.judge(ev)[0] == "count"


def test_no_evidence_either_way_is_both() -> None:
    cases = [_case("A1-01"), _case("R6-01", Verdict.FAIL, BAD)]
    assert conn_deaths.judge(conn_deaths.evidence(cases[-1], cases))[0] == "both"


def test_name_retitles_with_the_count_or_both() -> None:
    cases = [_case("A5-01[transfer-02]"), _case("A5-01[transfer-ff]", Verdict.FAIL, BAD)]
    death = Death("A5-01[transfer-ff]", DeathKind.CONNECTION_LEAK, "d", 49, 48)
    cause = _leak(["A5-01[transfer-ff]"])
    conn_deaths.name([cause], cases, [death])
    assert cause.confirmed and "freed" in cause.title and "opened 49 connections and closed 48" in cause.title
    assert any(h["key"] == "connection-count-leak" for h in cause.diagnosis["hypotheses"])
    lone = [_case("R6-01", Verdict.FAIL, BAD)]
    other = _leak(["R6-01"])
    conn_deaths.name([other], lone, [Death("R6-01", DeathKind.CONNECTION_LEAK, "d", 10, 9)])
    assert other.title.startswith("unconfirmed:") and not other.confirmed


def test_name_leaves_other_kinds_alone() -> None:
    cases = [_case("A5-01[transfer-02]"), _case("A5-01[transfer-ff]", Verdict.FAIL, BAD)]
    cause = RootCause("RC1", ("R2",), "dead", "e", ["A5-01[transfer-ff]"], kind="dead-after-input", confirmed=True)
    conn_deaths.name([cause], cases, [Death("A5-01[transfer-ff]", DeathKind.DEAD_AFTER_INPUT, "d", 3, 2)])
    assert cause.title == "dead"

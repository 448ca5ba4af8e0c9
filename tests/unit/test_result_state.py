"""E3 before the first cycle (engine/history_causes, diagnose/result_state): the pair E3-02 FAIL / E3-01 PASS is one
root cause, and a result request answered legally now confirms that the result is wrong only before a cycle."""

from __future__ import annotations

from conformance.diagnose import result_state
from conformance.engine.history_causes import RESULT_BEFORE_CYCLE, history_causes
from conformance.engine.rootcause import find_root_causes
from conformance.model.verdicts import CaseResult, Level, Verdict
from conformance.protocol.answers import block_value


def result(case_id: str, verdict: Verdict, code: int) -> CaseResult:
    out = CaseResult(case_id, case_id, ("E3",), Level.MUST, verdict, "seen")
    out.details["result_code"] = code
    return out


def test_the_first_result_request_failing_while_the_later_one_passes_is_a_history_cause() -> None:
    cases = [result("E3-01", Verdict.PASS, 1), result("E3-02", Verdict.FAIL, 0)]
    [(cause, members)] = history_causes(cases)
    assert cause.kind == RESULT_BEFORE_CYCLE and [m.id for m in members] == ["E3-02"]
    assert "ResultCode 0" in cause.title and "ResultCode 1" in cause.title and "before any cycle" in cause.title
    [first] = find_root_causes(cases)
    assert first.kind == RESULT_BEFORE_CYCLE and first.cases == ["E3-02"]


def test_no_history_cause_when_both_fail_or_the_first_passes() -> None:
    assert history_causes([result("E3-01", Verdict.FAIL, 0), result("E3-02", Verdict.FAIL, 0)]) == []
    assert history_causes([result("E3-01", Verdict.PASS, 1), result("E3-02", Verdict.PASS, 202)]) == []
    assert history_causes([result("E3-02", Verdict.FAIL, 0)]) == []


def test_the_block_value_is_read_from_the_bytes_in_either_byte_order() -> None:
    answer = bytes.fromhex("fefe0001102703010005000000" + "00000000" + "0000")
    assert block_value(answer) == 0
    assert block_value(bytes.fromhex("fefe0001102703010005000000" + "000000ca" + "0000")) == 202
    assert block_value(bytes.fromhex("fefe0001102703010005000000" + "ca000000" + "0000"), "little") == 202
    assert block_value(bytes.fromhex("fefe00011000000000000000" + "0000")) is None  # no block


def test_the_confirmed_title_names_the_cycle_and_the_result_codes() -> None:
    title = result_state.title_for(0, 1)
    assert "ResultCode 0" in title and "first cycle" in title and "now 1" in title and "E3" in title

"""The certify-robot cases on hand-built runs: IDs, clauses, levels, verdicts, evidence,
and the interval histogram in the HTML report."""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET

import pytest

from conformance.certify import checks
from conformance.certify.checks import judge
from conformance.certify.records import CertifyConfig, RunRecord
from conformance.engine.rootcause import find_root_causes
from conformance.model.signature import Sig, Signature
from conformance.model.verdicts import SuiteInfo, Verdict
from conformance.observed.connections import BY_SUITE, InjectionEvent
from conformance.protocol import DEFAULT_PROFILE, Action, ErrorCode, encode, pose_blocks, request
from conformance.report import render_html
from conformance.report.svg import histogram_svg
from tests.unit.test_observed_session import POSE, Fake, canonical, frame

NS = "{http://www.w3.org/2000/svg}"


def run_of(*fakes: Fake, **config) -> RunRecord:
    cfg = CertifyConfig(**config)
    return RunRecord(cfg, 0.0, 3.0, "127.0.0.1", 9004, 9004, [f.session for f in fakes], "complete", "done")


def by_id(cases) -> dict:
    return {c.id: c for c in cases}


def test_a_clean_session_passes_everything_that_applies():
    fake, _, _ = canonical()
    cases = by_id(judge(run_of(fake, jitter_tolerance=0.5)))
    assert cases["RB-S1-01"].verdict is Verdict.PASS
    assert cases["RB-T2-01"].verdict is Verdict.PASS and cases["RB-T2-02"].verdict is Verdict.PASS
    assert cases["RB-F7-01"].verdict is Verdict.SKIP and "no UDP datagram" in cases["RB-F7-01"].message
    assert cases["RB-B2-01"].verdict is Verdict.SKIP and "tolerance frame" in cases["RB-B2-01"].message
    failing = [c.id for c in cases.values() if c.verdict not in (Verdict.PASS, Verdict.SKIP)]
    assert not failing
    assert all(c.details["session"] == 1 for c in cases.values())


@pytest.mark.parametrize("mutate, case_id, clause", [
    (lambda b: b[:4] + b"\x10" + b[5:], "RB-F3-01", "F3"),
    (lambda b: b[:2] + b"\x00\x02" + b[4:], "RB-F2-01", "F2"),
    (lambda b: b[:5] + b"\x55" + b[6:], "RB-A5-01", "A5"),
    (lambda b: b[:12] + b"\x01" + b[13:], "RB-B3-01", "B3"),
    (lambda b: b[:-2] + DEFAULT_PROFILE.check_bytes(b[:-2]), "RB-F6-01", "F6"),
    (lambda b: b[:6] + b"\x02" + b[7:], "RB-B5-01", "B5"),
])
def test_each_broken_pose_fails_its_own_case(mutate, case_id, clause):
    fake = Fake()
    cmd, stream = fake.conn(0.0), fake.conn(0.01)
    fake.send(stream, 0.02, POSE)
    fake.send(stream, 0.04, mutate(POSE), error_code=ErrorCode.POSE_ERROR)
    fake.close(stream, 0.1)
    fake.close(cmd, 0.2)
    cases = by_id(judge(run_of(fake)))
    got = cases[case_id]
    assert got.verdict is Verdict.FAIL, got.message
    assert got.clauses == (clause,)
    assert f"[{clause}]" in got.message and "connection 2" in got.message
    assert got.received_hex == mutate(POSE).hex(" ")
    assert got.wire and got.wire[0].direction == "←"
    others = [c.id for c in cases.values() if c.verdict is Verdict.FAIL and c.id.startswith("RB-") and c.id != case_id
              and c.id not in ("RB-S1-01", "RB-T2-01", "RB-T2-02")]
    assert not others, others


def test_nan_is_non_strict_and_accepted_when_lenient():
    nan_pose = encode(request(Action.POSE, pose_blocks([(math.nan, 0, 0, 0, 0, 0)])))
    for strict, verdict in ((True, Verdict.NON_STRICT), (False, Verdict.INFORMATIONAL)):
        fake = Fake()
        cmd, stream = fake.conn(0.0), fake.conn(0.01)
        fake.send(stream, 0.02, nan_pose)
        fake.close(stream, 0.1)
        fake.close(cmd, 0.2)
        profile = DEFAULT_PROFILE.replace(strict=strict)
        cases = by_id(judge(run_of(fake, profile=profile)))
        if strict:
            assert cases["RB-B4-01"].verdict is verdict
        else:  # a lenient decoder accepts NaN: nothing to report
            assert cases["RB-B4-01"].verdict is Verdict.PASS


def test_byte_order_case():
    fake, _, stream = canonical()
    little = DEFAULT_PROFILE.replace(float_byte_order="little")
    fake.send(stream, 0.885, encode(request(Action.POSE, pose_blocks([(800.0, 1.0, 2.0, 3.0, 4.0, 5.0)])), little))
    got = by_id(judge(run_of(fake)))["RB-F4-01"]
    assert got.verdict is Verdict.FAIL and got.clauses == ("F4", "B4")
    assert "1 of " in got.message and "byte-swapped (800.0, 1.0, 2.0" in got.message


def test_left_open_fails_s5_with_the_reason():
    fake = Fake()
    cmd, stream = fake.conn(0.0), fake.conn(0.01)
    fake.send(stream, 0.02, POSE)
    fake.close(cmd, 0.5)
    fake.close(stream, 5.5, BY_SUITE, "closed by the suite: left open 5 s (--linger) after the command connection closed")
    got = by_id(judge(run_of(fake)))["RB-S5-01"]
    assert got.verdict is Verdict.FAIL
    assert "LEFT OPEN" in got.message and "--linger" in got.message


def test_a_stream_left_open_is_one_root_cause_s5_first_for_the_s1_and_s5_cases():
    fake = Fake()
    cmd, stream = fake.conn(0.0), fake.conn(0.01)
    for k in range(40):
        fake.send(stream, round(0.02 + 0.02 * k, 6), POSE)
    fake.send(cmd, 0.2, frame(Action.CYCLE_ON))
    fake.send(cmd, 0.8, frame(Action.CYCLE_OFF))
    fake.close(cmd, 2.0)
    fake.close(stream, 7.0, BY_SUITE, "closed by the suite: left open 5 s (--linger) after the command connection closed")
    cases = judge(run_of(fake, jitter_tolerance=0.5))
    got = by_id(cases)
    assert got["RB-S1-01"].verdict is Verdict.FAIL and "stream close missing" in got["RB-S1-01"].message
    assert got["RB-S5-01"].verdict is Verdict.FAIL
    assert got["RB-S1-01"].signature == got["RB-S5-01"].signature == Signature(Sig.LEFT_OPEN, "stream")
    causes = find_root_causes(cases)
    assert len(causes) == 1 and causes[0].clauses[0] == "S5" and set(causes[0].cases) == {"RB-S1-01", "RB-S5-01"}
    assert "stream connection open" in causes[0].title


def test_an_s1_failure_with_its_own_defect_is_not_blamed_on_a_left_open_connection():
    fake, cmd, stream = canonical(cycle_on=0.85, cycle_off=0.2)  # CycleOff before CycleOn: an S1 defect of its own
    got = by_id(judge(run_of(fake, jitter_tolerance=0.5)))
    assert got["RB-S1-01"].verdict is Verdict.FAIL and got["RB-S1-01"].signature is None
    assert got["RB-S5-01"].verdict is Verdict.PASS


def test_sessions_get_a_parameter_and_missing_ones_are_inconclusive():
    fake, _, _ = canonical()
    cases = by_id(judge(run_of(fake, sessions=3, jitter_tolerance=0.5)))
    assert cases["RB-S1-01[s1]"].verdict is Verdict.PASS
    assert cases["RB-S1-01[s2]"].verdict is Verdict.INCONCLUSIVE and cases["RB-S1-01[s3]"].verdict is Verdict.INCONCLUSIVE
    assert "RB-S1-01" not in cases


def test_the_suites_own_errors_are_error_cases(monkeypatch):
    fake, _, _ = canonical()
    run = run_of(fake)
    run.errors.append("handling bytes: RuntimeError: boom")

    def broken(ctx):
        raise ZeroDivisionError("judging went wrong")

    monkeypatch.setattr(checks, "close_case", broken)
    cases = by_id(judge(run))
    assert cases["RB-SUITE-01"].verdict is Verdict.ERROR and "boom" in cases["RB-SUITE-01"].message
    assert cases["RB-S5-01"].verdict is Verdict.ERROR and "ZeroDivisionError" in cases["RB-S5-01"].message
    assert cases["RB-S1-01"].verdict is Verdict.PASS  # the other checks still ran


def test_injection_that_never_applied_is_inconclusive():
    fake, _, _ = canonical()
    cases = by_id(judge(run_of(fake, inject=("busy",))))
    assert cases["RB-INJECT-BUSY"].verdict is Verdict.INCONCLUSIVE


def test_injection_reaction_is_recorded():
    fake = Fake()
    cmd, stream = fake.conn(0.0), fake.conn(0.01)
    fake.send(stream, 0.02, POSE)
    fake.send(cmd, 0.05, frame(Action.CYCLE_ON))
    fake.session.injected.append(InjectionEvent("close-mid-cycle", 0.05, 1, "inject close-mid-cycle: closed"))
    fake.close(cmd, 0.0501, "box", "inject close-mid-cycle")
    fake.send(stream, 0.06, POSE)
    fake.close(stream, 0.3)
    cases = by_id(judge(run_of(fake, inject=("close-mid-cycle",))))
    got = cases["RB-INJECT-CLOSE-MID-CYCLE"]
    assert got.verdict is Verdict.INFORMATIONAL
    assert "poses after it: 1" in got.message and "conn 2 (stream) robot at +300.0 ms" in got.message
    assert cases["RB-S1-01"].verdict is Verdict.INCONCLUSIVE


# -- the histogram in the report ----------------------------------------------------------------------------
def _svg(text: str) -> ET.Element:
    root = ET.fromstring(text)
    assert root.tag == f"{NS}svg" and "<script" not in text and "href" not in text
    return root


def test_histogram_svg():
    values = [20.0 + (i % 5) * 0.2 for i in range(100)] + [0.01] * 10 + [500.0]
    root = _svg(histogram_svg(values, 40, "intervals <&>", expected_ms=20.0))
    texts = ["".join(t.itertext()) for t in root.iter(f"{NS}text")]
    assert "intervals <&>" in texts
    assert any(t.startswith("expected 20") for t in texts)
    assert any("n=111" in t and "▲ 1 above" in t for t in texts)
    bars = [r for r in root.iter(f"{NS}rect") if r.get("height") and r.get("x") != "0"]
    assert 2 <= len(bars) <= 40


@pytest.mark.parametrize("values", [[], [math.nan], [5.0], [0.0, 0.0]])
def test_histogram_svg_edge_cases(values):
    _svg(histogram_svg(values, 10, "edge", expected_ms=None))


def test_the_html_report_draws_the_histogram_instead_of_a_details_row(tmp_path):
    fake, _, _ = canonical()
    cases = judge(run_of(fake))
    suite = SuiteInfo("0", "2026-01-01T00:00:00+00:00", 1.0, "robot at 127.0.0.1:40001 (client role)",
                      DEFAULT_PROFILE.to_dict())
    html = render_html(suite, cases, tmp_path)
    assert html.count('class="histogram"') == 2  # RB-T2-01 and RB-T2-02
    assert "<th>interval_histogram</th>" not in html
    assert "<th>stream</th>" in html
    broken = [c for c in cases if c.id == "RB-T2-01"]
    broken[0].details["interval_histogram"] = {"values_ms": "not a list"}
    html = render_html(suite, broken, tmp_path)
    assert 'class="histogram"' not in html and "<th>interval_histogram</th>" in html


# -- a T2 FAIL the robot's own starvation could explain (a loaded runner) ------------------------------
def test_a_t2_fail_says_when_the_robot_s_own_starvation_could_explain_it():
    from conformance.certify.robot_starvation import ROBOT_STARVED, robot_starved_note
    from conformance.harness.starvation import StarvationGauge

    contended = StarvationGauge()
    for k in range(12):  # PSI samples every 0.25 s from t=99.5: some task waited 100 ms for a CPU in each
        contended.note_pressure(99.5 + k * 0.25, 99.5 + k * 0.25, k * 100_000)
    times = [100.0 + i * 0.02 for i in range(100)]  # a 2 s stream
    note = robot_starved_note(80.0, times, "127.0.0.1", contended)
    assert ROBOT_STARVED in note and "waited 1000 ms" in note and "verdict stands" in note
    assert robot_starved_note(80.0, times, "192.0.2.7", contended) == ""  # a robot elsewhere has its own CPU
    assert robot_starved_note(5000.0, times, "::1", contended) == ""  # a breach longer than every stall stands
    assert robot_starved_note(0.0, times, "127.0.0.1", contended) == ""  # no breach, no note
    assert robot_starved_note(80.0, times, "127.0.0.1", StarvationGauge()) == ""  # no PSI samples: no evidence

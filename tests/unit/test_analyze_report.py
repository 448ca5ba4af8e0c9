"""An analysis as the suite's evidence (conformance/analyze/analysis_report.py): one case per
(clause, side), frame numbers in the message, the bytes of both sides, the plots."""

from __future__ import annotations

import json
import xml.etree.ElementTree as ET

from conformance.analyze import AnalyzeConfig, analyze, build_cases, write_analysis
from conformance.analyze.capture_catalogue import SPECS
from conformance.model.verdicts import Verdict
from conformance.protocol import Action, answer, encode, request
from tests.analyze_util import Capture, canonical, exchange


def test_every_case_of_the_catalogue_in_order_and_skip_when_nothing_to_judge(tmp_path):
    cap = Capture()
    canonical(cap)
    cases = build_cases(analyze(cap.write(tmp_path / "c.pcapng"), AnalyzeConfig(jitter_tolerance=3.0)))
    assert [c.id for c in cases] == [s.id for s in SPECS.values()]
    by_id = {c.id: c for c in cases}
    assert by_id["OBS-F7-box"].verdict is Verdict.SKIP and "nothing in the capture" in by_id["OBS-F7-box"].message
    assert by_id["OBS-S3-box"].verdict is Verdict.PASS and by_id["OBS-S3-box"].message.startswith("20 poses judged")
    assert all(c.pcap and c.pcap.endswith("c.pcapng") for c in cases)
    assert by_id["OBS-T2-box"].latencies_ms and "latency" in by_id["OBS-T2-box"].details
    assert by_id["OBS-T1-box"].latencies_ms  # CycleOn and CycleOff
    assert by_id["OBS-T2-robot"].details["interval_histogram"]["expected_ms"] == 20.0


def test_a_finding_names_its_frames_and_carries_both_sides_bytes(tmp_path):
    cap = Capture()
    conn = cap.tcp(41000)
    req, bad = encode(request(Action.NONE)), encode(answer(Action.CYCLE_ON))
    exchange(conn, req, bad)
    conn.close()
    case = {c.id: c for c in build_cases(analyze(cap.write(tmp_path / "c.pcapng")))}["OBS-A2-box"]
    assert case.verdict is Verdict.FAIL and case.message.startswith("frames 4, 5: ")
    assert case.sent_hex == req.hex(" ") and case.received_hex == bad.hex(" ")
    assert case.details["frames"] == [4, 5]
    assert "FAIL (1):" in case.observed


def test_the_reports_say_observed(tmp_path):
    cap = Capture()
    conn = cap.tcp(41000)
    exchange(conn, encode(request(Action.NONE)), encode(answer(Action.CYCLE_ON)))
    conn.close()
    suite, cases = write_analysis(analyze(cap.write(tmp_path / "c.pcapng")), tmp_path / "r", "isight-conformance analyze c")
    doc = json.loads((tmp_path / "r" / "summary.json").read_text())
    assert doc["suite"]["role"] == "observed" and doc["suite"]["command"] == "isight-conformance analyze c"
    assert doc["suite"]["cases_total"] == len(cases) == len(doc["cases"])
    html = (tmp_path / "r" / "report.html").read_text()
    assert "Captured robot ↔ AI Box traffic judged against PROTOCOL.md, both roles" in html
    assert "Robot → box (hex)" in html and "Box → robot (hex)" in html and "The traffic in" in html
    assert "<svg" in html
    failures = [tc for tc in ET.parse(tmp_path / "r" / "junit.xml").getroot().iter("testcase")
                if tc.find("failure") is not None]
    # the box's answer does not echo (A2); a session of one NONE is not a canonical session (S1)
    assert [tc.get("name").split()[0] for tc in failures] == ["OBS-A2-box", "OBS-S1-robot"]

"""junit.xml: structure, verdict mapping, escaping, and the attributes CI tools read.

No JUnit XSD ships in an installed package here, so the schema rules Jenkins' and
GitLab's importers rely on are checked directly (element nesting, required and
numeric attributes, one outcome element per testcase).
"""

from __future__ import annotations

import os
import re
import xml.etree.ElementTree as ET

from conformance.report import write_junit
from conformance.report.junit import junit_timestamp
from conformance.suite.verdicts import CaseResult, Level, Verdict

from .test_report_summary import HOSTILE, sample_cases, sample_suite

OUTCOMES = {"failure", "error", "skipped"}
TESTCASE_CHILDREN = OUTCOMES | {"properties", "system-out", "system-err"}


def _write(tmp_path, cases=None, suite=None):
    path = tmp_path / "junit.xml"
    write_junit(path, suite or sample_suite(), sample_cases() if cases is None else cases)
    return path, ET.parse(path).getroot()


def _cases_by_id(root):
    return {tc.get("name").split(" ", 1)[0]: tc for tc in root.iter("testcase")}


def test_suite_element_and_counts(tmp_path):
    path, root = _write(tmp_path)
    assert path.read_bytes().startswith(b"<?xml version='1.0' encoding='utf-8'?>")
    assert root.tag == "testsuites"
    suites = root.findall("testsuite")
    assert len(suites) == 1
    ts = suites[0]
    assert ts.get("name") == "isight-conformance"
    # 8 cases: FAIL, NON-STRICT, PASS, INCONCLUSIVE, INFORMATIONAL, SKIP, ERROR, PASS
    assert (ts.get("tests"), ts.get("failures"), ts.get("errors"), ts.get("skipped")) == ("8", "1", "1", "2")
    assert ts.get("time") == "187.400"
    assert ts.get("timestamp") == "2026-05-09T07:35:25"
    for attr in ("tests", "failures", "errors", "skipped", "time"):
        assert root.get(attr) == ts.get(attr)
    assert len(ts.findall("testcase")) == 8


def test_suite_properties(tmp_path):
    suite = sample_suite(udp_target="10.0.0.5:9005", expected_failures="xfail.txt")
    _, root = _write(tmp_path, suite=suite)
    props = {p.get("name"): p.get("value") for p in root.find("testsuite/properties")}
    assert props["target"] == "10.0.0.5:9004"
    assert props["udp_target"] == "10.0.0.5:9005"
    assert props["version"] == "0.1.0"
    assert props["extension"] == "detected"
    assert props["expected_failures"] == "xfail.txt"
    assert props["command"].startswith("isight-conformance run")
    for key, value in suite.profile.items():
        assert props[f"profile.{key}"] == str(getattr(value, "value", value))
    assert props["profile.first_index"] == "1"
    assert props["totals.FAIL"] == "1"


def test_testcase_names_classes_and_times(tmp_path):
    _, root = _write(tmp_path)
    cases = sample_cases()
    tcs = root.findall("testsuite/testcase")
    for case, tc in zip(cases, tcs):
        assert tc.get("name") == f"{case.id} {case.title}"
        assert tc.get("classname") == f"isight.{case.clauses[0][0]}"
        assert float(tc.get("time")) == round(case.duration_s, 3)
        props = {p.get("name"): p.get("value") for p in tc.find("properties")}
        assert props == {"verdict": case.verdict.value, "level": case.level.value, "clauses": " ".join(case.clauses)}


def test_verdict_mapping(tmp_path):
    _, root = _write(tmp_path)
    tc = _cases_by_id(root)

    fail = tc["F1-01"].find("failure")
    assert fail.get("type") == "FAIL" and fail.get("message") == "box answered 0000 to a frame starting FF FE"
    for needle in ("requirement: R1", "expected: no answer", "observed: answer 23/0000", "sent (hex):",
                   "ff fe 00 01 01 23 01 01 00 19", "received (hex):", "fe fe 00 01 10 23", "pcap: pcaps/F1-01.pcapng"):
        assert needle in fail.text

    err = tc["R5-03"].find("error")
    assert err.get("type") == "ERROR" and "too many open files" in err.get("message")
    assert "traceback: Traceback" in err.text

    assert tc["F7-01"].find("skipped").get("message") == "no --udp-target"
    inconclusive = tc["S2-01"].find("skipped")
    assert inconclusive.get("message").startswith("INCONCLUSIVE")
    assert "0001 (not ready)" in inconclusive.get("message")

    for cid, verdict in (("A3-02", "NON-STRICT"), ("S3-02", "INFORMATIONAL")):
        el = tc[cid]
        assert not OUTCOMES & {child.tag for child in el}  # they pass
        assert f"verdict: {verdict}" in el.find("system-out").text
        assert el.find("properties/property[@name='verdict']").get("value") == verdict
    assert "answered 0002" in tc["S3-02"].find("system-out").text

    for cid in ("T2-01", "B3-01"):
        assert [child.tag for child in tc[cid]] == ["properties"]


def test_ci_attribute_set(tmp_path):
    """What Jenkins' and GitLab's JUnit importers read, checked as a schema would."""
    _, root = _write(tmp_path)
    ts = root.find("testsuite")
    assert [child.tag for child in ts][0] == "properties"
    assert {child.tag for child in ts} == {"properties", "testcase"}
    for attr in ("tests", "failures", "errors", "skipped"):
        assert re.fullmatch(r"\d+", ts.get(attr))
    assert re.fullmatch(r"\d+\.\d{3}", ts.get("time"))
    assert re.fullmatch(r"\d{4}-\d\d-\d\dT\d\d:\d\d:\d\d", ts.get("timestamp"))
    for tc in ts.iter("testcase"):
        assert {"name", "classname", "time"} <= set(tc.attrib)
        assert re.fullmatch(r"\d+\.\d{3}", tc.get("time"))
        tags = [child.tag for child in tc]
        assert set(tags) <= TESTCASE_CHILDREN
        assert len([t for t in tags if t in OUTCOMES]) <= 1
        for child in tc:
            if child.tag in OUTCOMES:
                assert "message" in child.attrib
            if child.tag in ("failure", "error"):
                assert "type" in child.attrib


def test_hostile_text_is_escaped_and_valid_xml(tmp_path):
    nasty = CaseResult("F2-09", HOSTILE, ("F2",), Level.MUST, Verdict.FAIL, message=HOSTILE, observed=HOSTILE,
                       sent_hex="\x00\x01 not hex", details={"raw": b"\x00\xff", HOSTILE: HOSTILE})
    path, root = _write(tmp_path, cases=[nasty])
    raw = path.read_bytes()
    raw.decode("utf-8")
    assert b"<script>" not in raw
    assert not re.search(rb"[\x00-\x08\x0b\x0c\x0e-\x1f]", raw)
    tc = root.find("testsuite/testcase")
    assert "<script>alert('x')</script>" in tc.get("name")  # escaped on disk, intact when parsed
    assert "\\x00\\x1b[31m\\ud800" in tc.find("failure").get("message")
    assert "\n" not in tc.find("failure").get("message")
    assert "]]>" in tc.find("failure").text


def test_empty_run_and_missing_clauses(tmp_path):
    _, root = _write(tmp_path, cases=[])
    ts = root.find("testsuite")
    assert ts.get("tests") == "0" and ts.findall("testcase") == []
    _, root = _write(tmp_path, cases=[CaseResult("X-1", "no clause", (), Level.MAY, Verdict.PASS)])
    assert root.find("testsuite/testcase").get("classname") == "isight.other"


def test_write_is_atomic(tmp_path):
    _write(tmp_path)
    _write(tmp_path, cases=[])
    assert os.listdir(tmp_path) == ["junit.xml"]


def test_timestamp_normalisation():
    assert junit_timestamp("2026-05-09T09:35:25.5+02:00") == "2026-05-09T07:35:25"
    assert junit_timestamp("2026-05-09T07:35:25Z") == "2026-05-09T07:35:25"
    assert junit_timestamp("2026-05-09T07:35:25") == "2026-05-09T07:35:25"
    assert junit_timestamp("yesterday") == "yesterday"

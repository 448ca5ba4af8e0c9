"""junit.xml: Jenkins' schema, the counts CI tools read back, verdict mapping, escaping.

``junit-10.xsd`` in tests/ is Jenkins' JUnit schema, copied unchanged from the
xUnit plugin (https://github.com/jenkinsci/xunit-plugin, file
src/main/resources/org/jenkinsci/plugins/xunit/types/model/xsd/junit-10.xsd at commit
8c515de2804b3fd591a3b0f1ff8908a1b1a41887; MIT licence, Copyright (c) 2014 Gregory
Boissinot, the licence text is in the file). Every junit.xml written here is validated
against it with ``xmlschema`` and read back with ``junitparser`` as CI tools read it.
"""

from __future__ import annotations

import os
import re
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

from conformance.model.verdicts import CaseResult, Level, Verdict
from conformance.report import write_junit, write_summary
from conformance.report.clausetext import clause_text
from conformance.report.junit import junit_timestamp
from tests.unit.test_report_summary import HOSTILE, sample_cases, sample_root_causes, sample_suite

xmlschema = pytest.importorskip("xmlschema", reason="xmlschema is in the test extra: pip install -e '.[test]'")
junitparser = pytest.importorskip("junitparser", reason="junitparser is in the test extra: pip install -e '.[test]'")

OUTCOMES = {"failure", "error", "skipped"}
TESTCASE_CHILDREN = OUTCOMES | {"system-out", "system-err"}
SCHEMA = xmlschema.XMLSchema(str(Path(__file__).resolve().parents[1] / "junit-10.xsd"))


def _write(tmp_path, cases=None, suite=None, root_causes=()):
    path = tmp_path / "junit.xml"
    write_junit(path, suite or sample_suite(), sample_cases() if cases is None else cases, root_causes)
    errors = [f"{e.path}: {e.reason}" for e in SCHEMA.iter_errors(str(path))]
    assert errors == [], errors[:5]  # every file written here validates against junit-10.xsd
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
    for attr in ("tests", "failures", "errors", "time"):
        assert root.get(attr) == ts.get(attr)
    assert root.get("skipped") is None  # junit-10.xsd has no skipped on <testsuites>
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
        assert tc.find("properties") is None  # junit-10.xsd allows none in a testcase
        out = tc.find("system-out").text.splitlines()
        assert out[0].startswith(case.verdict.value)
        assert out[1] == f"verdict: {case.verdict.value}  level: {case.level.value}  clauses: {', '.join(case.clauses)}"


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
        assert el.find("system-out").text.startswith(f"{verdict}: ")
        assert f"verdict: {verdict}" in el.find("system-out").text
    assert "answered 0002" in tc["S3-02"].find("system-out").text
    assert "(a SHOULD is broken; the case passes in CI)" in tc["A3-02"].find("system-out").text.splitlines()[0]

    for cid in ("T2-01", "B3-01"):
        assert [child.tag for child in tc[cid]] == ["system-out"]
        assert tc[cid].find("system-out").text.startswith("PASS")
    # a failing case's system-out is the short head; the evidence is in the failure body only
    out = tc["F1-01"].find("system-out").text
    assert "pcap: pcaps/F1-01.pcapng" in out and "ff fe 00 01" not in out


def test_ci_attribute_set(tmp_path):
    """What Jenkins' and GitLab's JUnit importers read, checked as a schema would."""
    _, root = _write(tmp_path)
    ts = root.find("testsuite")
    assert [child.tag for child in ts][0] == "properties"
    assert [child.tag for child in ts][-1] == "system-out"
    assert {child.tag for child in ts} == {"properties", "testcase", "system-out"}
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


# -- read back as CI tools do ----------------------------------------------------------------
def _read_back(path):
    xml = junitparser.JUnitXml.fromfile(str(path))
    suites = list(xml) if isinstance(xml, junitparser.JUnitXml) else [xml]
    counts = {"tests": 0, "failures": 0, "errors": 0, "skipped": 0, "passed": 0}
    for suite in suites:
        for case in suite:
            counts["tests"] += 1
            kinds = {type(r).__name__ for r in case.result}
            assert len(kinds) <= 1
            counts["failures"] += "Failure" in kinds
            counts["errors"] += "Error" in kinds
            counts["skipped"] += "Skipped" in kinds
            counts["passed"] += case.is_passed
    return suites, counts


@pytest.mark.parametrize("variant", ["sample", "root-causes", "incomplete", "empty"])
def test_junitparser_counts_match_summary_json(tmp_path, variant):
    suite, cases, rcs = sample_suite(), sample_cases(), []
    if variant == "root-causes":
        cases, rcs = sample_root_causes()
    elif variant == "incomplete":
        suite = sample_suite(complete=False, cases_total=12, not_run=["R2-01", "R2-02", "S4-01", "S5-01"])
    elif variant == "empty":
        cases = []
    path, _ = _write(tmp_path, cases=cases, suite=suite, root_causes=rcs)
    summary = write_summary(tmp_path / "summary.json", suite, cases, rcs)["totals"]
    suites, counts = _read_back(path)
    assert counts == {
        "tests": len(cases),
        "failures": summary["FAIL"],
        "errors": summary["ERROR"],
        "skipped": summary["SKIP"] + summary["INCONCLUSIVE"],
        "passed": summary["PASS"] + summary["NON-STRICT"] + summary["INFORMATIONAL"],
    }
    (ts,) = suites
    assert (ts.tests, ts.failures, ts.errors, ts.skipped) == (
        counts["tests"], counts["failures"], counts["errors"], counts["skipped"])


def test_non_strict_stays_visible(tmp_path):
    cases, rcs = sample_root_causes()
    path, root = _write(tmp_path, cases=cases, root_causes=rcs)
    suites, _ = _read_back(path)
    by_name = {c.name.split(" ", 1)[0]: c for c in suites[0]}
    assert by_name["A3-02"].is_passed and by_name["A3-02"].system_out.startswith("NON-STRICT: ")
    ts = root.find("testsuite")
    props = {p.get("name"): p.get("value") for p in ts.find("properties")}
    assert props["nonstrict"] == "A3-01[g0] A3-01[g1] A3-02" and props["totals.NON-STRICT"] == "3"
    out = ts.find("system-out").text
    assert "3 NON-STRICT (a SHOULD is broken; these cases pass in CI):" in out
    assert "  NON-STRICT A3-01[g1] [A3, B3] A3: a parse error SHOULD be answered 1001" in out


def test_root_causes_and_clause_texts(tmp_path):
    cases, rcs = sample_root_causes()
    _, root = _write(tmp_path, cases=cases, root_causes=rcs)
    ts = root.find("testsuite")
    props = {p.get("name"): p.get("value") for p in ts.find("properties")}
    assert props["root_cause.RC1"] == "F2, A2: every answer carries version 01 00 instead of 00 01 (14 cases)"
    assert "root cause RC1 [F2, A2] every answer carries version 01 00 instead of 00 01 (14 cases)" in \
        ts.find("system-out").text
    tc = _cases_by_id(root)
    body = tc["A5-01[v03]"].find("failure").text
    assert "root cause: RC1 [F2, A2] every answer carries version 01 00 instead of 00 01" in body
    a5 = clause_text("A5")
    assert f"\nclause A5 ({a5.level}): {a5.text}\n" in body
    assert "clause R1" not in body  # the verdict judged A5 only (its requirement says so)
    assert "root cause" not in tc["F1-01"].find("failure").text
    # the sample's F1-01 requirement starts "R1:": R1 is the clause shown
    assert re.search(r"^clause R1( \(MUST\))?: ", tc["F1-01"].find("failure").text, re.M)


def test_incomplete_run(tmp_path):
    suite = sample_suite(complete=False, cases_total=80, not_run=[f"R2-{i:02d}" for i in range(72)])
    _, root = _write(tmp_path, suite=suite)
    ts = root.find("testsuite")
    props = {p.get("name"): p.get("value") for p in ts.find("properties")}
    assert props["complete"] == "false" and props["cases_total"] == "80"
    assert props["not_run"].startswith("R2-00 R2-01") and props["not_run"].endswith("… (72 in all)")
    assert props["overall"].startswith("INCOMPLETE (8 of 80 cases run)")
    out = ts.find("system-out").text.splitlines()
    assert out[0].startswith("INCOMPLETE (8 of 80 cases run)")
    assert out[-1].startswith("not run (72): R2-00 R2-01")


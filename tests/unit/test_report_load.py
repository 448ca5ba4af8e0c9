"""conformance.report.load: reading a summary.json back, and one-line errors for bad paths."""

from __future__ import annotations

import json

import pytest

from conformance.report.load import (
    SummaryError,
    cases_of,
    load_summary,
    root_causes_of,
    suite_of,
    summary_path,
)
from conformance.report.summary import write_summary
from tests.unit.test_report_summary import sample_cases, sample_root_causes, sample_suite


def test_round_trip(tmp_path):
    cases, rcs = sample_root_causes()
    suite = sample_suite(complete=False, cases_total=30, not_run=["R2-01"])
    write_summary(tmp_path / "summary.json", suite, cases, rcs)
    doc = load_summary(tmp_path)  # a report directory
    assert doc == load_summary(tmp_path / "summary.json")
    back = suite_of(doc)
    assert (back.target, back.complete, back.cases_total, back.not_run) == (suite.target, False, 30, ["R2-01"])
    assert [c.to_summary() for c in cases_of(doc)] == doc["cases"]
    assert [r.to_dict() for r in root_causes_of(doc)] == [r.to_dict() for r in rcs]


def test_an_older_summary_without_new_fields_loads(tmp_path):
    doc = write_summary(tmp_path / "summary.json", sample_suite(), sample_cases())
    for key in ("complete", "cases_total", "not_run", "registry_version", "role"):
        del doc["suite"][key]
    del doc["root_causes"]
    for case in doc["cases"]:
        del case["root_cause"]
    (tmp_path / "summary.json").write_text(json.dumps(doc))
    loaded = load_summary(tmp_path / "summary.json")
    assert suite_of(loaded).complete is True and root_causes_of(loaded) == []
    assert [c.verdict for c in cases_of(loaded)] == [c.verdict for c in sample_cases()]


@pytest.mark.parametrize(("content", "words"), [
    (None, "no such file"),
    (b"\xff\xfe not utf-8", "not JSON"),
    (b"{\"suite\": ", "not JSON"),
    (b"[1, 2]", "not an isight-conformance summary.json (the top level is not an object)"),
    (b"{\"suite\": {}, \"cases\": {}}", "no 'suite' object and 'cases' list"),
    (b"{\"suite\": {}, \"cases\": [{\"id\": \"A\", \"verdict\": \"MAYBE\"}]}", "case A has no known verdict"),
    (b"{\"suite\": {}, \"cases\": [{\"verdict\": \"PASS\"}]}", "case 0 has no id"),
])
def test_bad_files_are_one_line_errors(tmp_path, content, words):
    path = tmp_path / "summary.json"
    if content is not None:
        path.write_bytes(content)
    with pytest.raises(SummaryError) as info:
        load_summary(path)
    message = str(info.value)
    assert words in message and "\n" not in message and str(path) in message


def test_a_directory_without_a_summary(tmp_path):
    with pytest.raises(SummaryError, match="holds no summary.json"):
        load_summary(tmp_path)
    assert summary_path(tmp_path) == tmp_path / "summary.json"
    assert summary_path(tmp_path / "x.json") == tmp_path / "x.json"

"""conformance.report.diff: comparing two runs (pure), and its text, Markdown and JSON."""

from __future__ import annotations

import dataclasses
import json

from conformance.model.verdicts import CaseResult, Level, RootCause, Verdict
from conformance.report.diff import MARKDOWN_ROWS, compare, render, render_markdown, render_text, summary_line
from conformance.report.summary import write_summary
from tests.unit.test_report_summary import sample_cases, sample_suite


def _docs(tmp_path, new_cases, old_cases=None, new_suite=None, old_rcs=(), new_rcs=()):
    old = write_summary(tmp_path / "old.json", sample_suite(), sample_cases() if old_cases is None else old_cases,
                        old_rcs)
    new = write_summary(tmp_path / "new.json", new_suite or sample_suite(), new_cases, new_rcs)
    return old, new


def _with(cases, **verdicts):
    return [dataclasses.replace(c, verdict=Verdict(verdicts[c.id.replace("-", "_")]), message=f"now {c.id}")
            if c.id.replace("-", "_") in verdicts else c for c in cases]


def test_identical_runs_are_not_worse(tmp_path):
    old, new = _docs(tmp_path, sample_cases())
    diff = compare(old, new)
    assert not diff.got_worse
    assert diff.counts() == {"worse": 0, "better": 0, "changed": 0, "added": 0, "removed": 0, "not_run": 0,
                             "unchanged": 8}
    assert diff.old_overall == diff.new_overall
    assert render_text(diff).splitlines()[-1] == "not worse: " + summary_line(diff)


def test_worse_better_changed(tmp_path):
    # B3-01 PASS→FAIL, T2-01 PASS→NON-STRICT, A3-02 NON-STRICT→FAIL (all worse);
    # F1-01 FAIL→PASS, R5-03 ERROR→NON-STRICT (better); S2-01 INCONCLUSIVE→PASS, F7-01 SKIP→INFORMATIONAL (changed)
    new_cases = _with(sample_cases(), B3_01="FAIL", T2_01="NON-STRICT", A3_02="FAIL", F1_01="PASS",
                      R5_03="NON-STRICT", S2_01="PASS", F7_01="INFORMATIONAL")
    old, new = _docs(tmp_path, new_cases)
    diff = compare(old, new, "old.json", "new.json")
    assert diff.got_worse
    assert [(c.id, c.old, c.new) for c in diff.worse] == [
        ("A3-02", "NON-STRICT", "FAIL"), ("B3-01", "PASS", "FAIL"), ("T2-01", "PASS", "NON-STRICT")]
    assert [(c.id, c.old, c.new) for c in diff.better] == [("F1-01", "FAIL", "PASS"), ("R5-03", "ERROR", "NON-STRICT")]
    assert {(c.id, c.old, c.new) for c in diff.changed} == {("S2-01", "INCONCLUSIVE", "PASS"),
                                                            ("F7-01", "SKIP", "INFORMATIONAL")}
    assert diff.unchanged == 1
    assert diff.worse[1].clauses == ("B3",) and diff.worse[1].message == "now B3-01"
    assert diff.old_overall.startswith("DOES NOT CONFORM: 1 FAIL, 1 ERROR")
    assert diff.new_overall.startswith("DOES NOT CONFORM: 2 FAIL, 0 ERROR")


def test_a_pass_that_becomes_inconclusive_is_a_change_not_a_regression(tmp_path):
    old, new = _docs(tmp_path, _with(sample_cases(), B3_01="INCONCLUSIVE"))
    diff = compare(old, new)
    assert not diff.got_worse and [c.id for c in diff.changed] == ["B3-01"]


def test_added_removed_and_not_run(tmp_path):
    base = sample_cases()
    extra = [CaseResult("E9-01", "new ok", ("E1",), Level.MUST, Verdict.PASS),
             CaseResult("E9-02", "new bad", ("E2",), Level.MUST, Verdict.FAIL, message="E2: 409 missing")]
    new_cases = [c for c in base if c.id not in ("B3-01", "T2-01")] + extra
    suite = sample_suite(complete=False, cases_total=10, not_run=["T2-01"])
    old, new = _docs(tmp_path, new_cases, new_suite=suite)
    diff = compare(old, new)
    assert [c.id for c in diff.added] == ["E9-01"]
    assert [(c.id, c.old, c.new) for c in diff.worse] == [("E9-02", None, "FAIL")]  # a new FAIL is worse
    assert [(c.id, c.old, c.new) for c in diff.removed] == [("B3-01", "PASS", None)]
    assert [c.id for c in diff.not_run] == ["T2-01"]  # cut short, not removed
    assert diff.new_overall.startswith("INCOMPLETE (8 of 10 cases run)")
    text = render_text(diff)
    assert "(new case) → FAIL" in text and "PASS → (gone)" in text
    assert "Not run in NEW (it was cut short) (1):" in text
    assert summary_line(diff).endswith(", 1 not run")


def test_context_and_root_causes(tmp_path):
    rc_old = RootCause("RC1", ("S4",), "serves one connection at a time", "", ["A1-01"], kind="one-connection")
    rc_new = RootCause("RC1", ("F2", "A2"), "every answer malformed", "fefe0100", ["B3-01"], kind="malformed-answers")
    suite = sample_suite(version="0.2.0", profile={**sample_suite().profile, "first_index": 0})
    old, new = _docs(tmp_path, _with(sample_cases(), B3_01="FAIL"), new_suite=suite, old_rcs=[rc_old],
                     new_rcs=[rc_new])
    diff = compare(old, new)
    assert "version: 0.1.0 → 0.2.0" in diff.context and "profile.first_index: 1 → 0" in diff.context
    assert diff.new_root_causes == ["RC1 [F2, A2] every answer malformed (1 cases)"]
    assert diff.gone_root_causes == ["RC1 [S4] serves one connection at a time (1 cases)"]
    text = render_text(diff)
    assert "Runs differ in: version: 0.1.0 → 0.2.0; profile.first_index: 1 → 0" in text
    assert "New root causes (1):\n  RC1 [F2, A2] every answer malformed" in text


def test_markdown_for_a_ci_comment(tmp_path):
    many = [CaseResult(f"R1-{i:03d}", "t", ("R1",), Level.MUST, Verdict.PASS) for i in range(MARKDOWN_ROWS + 5)]
    worse = [dataclasses.replace(c, verdict=Verdict.FAIL, message="R1: answered 0000 | to <garbage>") for c in many]
    old, new = _docs(tmp_path, worse, old_cases=many)
    md = render_markdown(compare(old, new, "a/summary.json", "b/summary.json"))
    assert md.startswith(f"### iSight conformance: **Got worse**: {MARKDOWN_ROWS + 5} worse")
    assert "| OLD | a/summary.json" in md and "| NEW | b/summary.json" in md
    assert f"#### Got worse ({MARKDOWN_ROWS + 5})" in md
    assert "| `R1-000` | R1 | PASS → FAIL | R1: answered 0000 \\| to &lt;garbage&gt; |" in md
    assert "| … | | | 5 more" in md
    assert md.count("| `R1-") == MARKDOWN_ROWS
    old, new = _docs(tmp_path, many, old_cases=many)
    assert render_markdown(compare(old, new)).startswith("### iSight conformance: No regression: 0 worse")


def test_json_round_trips(tmp_path):
    old, new = _docs(tmp_path, _with(sample_cases(), B3_01="FAIL", F1_01="PASS"))
    doc = json.loads(render(compare(old, new), "json"))
    assert doc["got_worse"] is True
    assert doc["counts"]["worse"] == 1 and doc["counts"]["better"] == 1
    assert doc["worse"][0] == {"id": "B3-01", "clauses": ["B3"], "title": "Indexes rise by one", "old": "PASS",
                               "new": "FAIL", "message": "now B3-01", "root_cause": None}
    assert render(compare(old, new), "text").endswith("\n")

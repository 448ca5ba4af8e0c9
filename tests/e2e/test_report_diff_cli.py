"""``isight-conformance diff`` and ``run --baseline`` (exit codes, formats, bad paths)."""

from __future__ import annotations

import dataclasses
import json
import subprocess
import sys
from pathlib import Path

import pytest
from rich.console import Console

from conformance.commands import main
from conformance.model.verdicts import Verdict
from conformance.protocol import ErrorCode, answer, encode
from conformance.report import write_reports
from conformance.report.load import SummaryError
from conformance.report.run_comparison import load_baseline, print_comparison
from conformance.report.summary import write_summary
from tests.boxes import ScriptedBox, answering
from tests.unit.test_report_summary import sample_cases, sample_suite


def _runs(tmp_path: Path, worse: bool) -> tuple[Path, Path]:
    old, new = tmp_path / "old", tmp_path / "new"
    write_summary(old / "summary.json", sample_suite(), sample_cases())
    cases = sample_cases()
    if worse:
        cases = [dataclasses.replace(c, verdict=Verdict.FAIL, message="broke") if c.id == "B3-01" else c for c in cases]
    write_summary(new / "summary.json", sample_suite(), cases)
    return old, new


def test_exit_status_follows_what_got_worse(tmp_path, capsys):
    old, new = _runs(tmp_path, worse=False)
    assert main(["diff", str(old), str(new / "summary.json")]) == 0
    assert capsys.readouterr().out.splitlines()[-1].startswith("not worse: 0 worse")
    old, new = _runs(tmp_path, worse=True)
    assert main(["diff", str(old), str(new)]) == 1
    out = capsys.readouterr().out
    assert "Got worse (1):" in out and "PASS → FAIL  B3-01  [B3]  broke" in out
    assert main(["diff", str(new), str(old)]) == 0  # the other way round it got better
    assert "Got better (1):" in capsys.readouterr().out


@pytest.mark.parametrize("fmt", ["json", "markdown", "text"])
def test_formats_and_output_file(tmp_path, capsys, fmt):
    old, new = _runs(tmp_path, worse=True)
    out_file = tmp_path / "out" / f"diff.{fmt}"
    assert main(["diff", str(old), str(new), "--format", fmt, "-o", str(out_file)]) == 1
    printed = capsys.readouterr().out
    assert out_file.read_text(encoding="utf-8") == printed
    if fmt == "json":
        assert json.loads(printed)["worse"][0]["id"] == "B3-01"
    elif fmt == "markdown":
        assert printed.startswith("### iSight conformance: **Got worse**")
        assert "| `B3-01` | B3 | PASS → FAIL | broke |" in printed


def test_bad_paths_exit_2_with_one_line(tmp_path, capsys):
    old, _ = _runs(tmp_path, worse=False)
    (tmp_path / "junk.json").write_text("[]")
    for args in ([str(old), str(tmp_path / "missing.json")], [str(tmp_path / "junk.json"), str(old)],
                 [str(tmp_path / "empty-dir"), str(old)]):
        (tmp_path / "empty-dir").mkdir(exist_ok=True)
        assert main(["diff", *args]) == 2, args
        captured = capsys.readouterr()
        assert captured.out == ""
        assert captured.err.count("\n") == 1 and captured.err.startswith("isight-conformance diff: ")
        assert "Traceback" not in captured.err


def test_registered_in_the_command():
    proc = subprocess.run([sys.executable, "-m", "conformance", "diff", "--help"], capture_output=True, text=True,
                          timeout=60)
    assert proc.returncode == 0 and "what got worse" in proc.stdout and "--format" in proc.stdout


def test_the_report_writers_apply_the_baseline_once_and_the_run_prints_it(tmp_path):
    old, new = _runs(tmp_path, worse=True)
    worse = [dataclasses.replace(c, verdict=Verdict.FAIL, message="broke") if c.id == "B3-01" else c
             for c in sample_cases()]
    console = Console(file=__import__("io").StringIO(), width=100)
    assert write_reports(new, sample_suite(), worse) is None
    print_comparison(None, None, console)
    assert console.file.getvalue() == ""
    baseline = load_baseline(old)
    assert baseline is not None
    baseline = dataclasses.replace(baseline, label="old")
    diff = write_reports(new, sample_suite(), worse, baseline=baseline)
    print_comparison(baseline, diff, console)
    assert diff is not None and diff.got_worse
    assert "Compared with the baseline old:" in console.file.getvalue()
    html = (new / "report.html").read_text(encoding="utf-8")
    assert 'id="baseline"' in html and "PASS → FAIL" in html
    with pytest.raises(SummaryError):
        load_baseline(tmp_path / "nope")


def _run(tmp_path: Path, *args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "conformance", "run", "--quiet", "--capture", "off",
                           "--cases", "A4*", *args], capture_output=True, text=True, timeout=200, cwd=tmp_path)


@pytest.mark.timeout(300)
def test_run_with_a_baseline(tmp_path):
    proc = _run(tmp_path, "--baseline", str(tmp_path / "missing"))
    assert proc.returncode == 2 and proc.stderr.count("\n") == 1 and "missing" in proc.stderr  # before the run
    assert not (tmp_path / "reports").exists()
    proc = _run(tmp_path, "--report-dir", "good")
    assert proc.returncode == 0, proc.stdout + proc.stderr
    # a box that answers every request 1001, NONE included: A4 cases now FAIL
    with ScriptedBox(answering(lambda f: encode(answer(f.action, ErrorCode.POSE_ERROR)))) as box:
        proc = _run(tmp_path, "--report-dir", "bad", "--target", box.target, "--baseline", "good")
    assert proc.returncode == 1, proc.stdout + proc.stderr
    assert "Compared with the baseline good:" in proc.stdout
    assert "Got worse (" in proc.stdout and "→ FAIL" in proc.stdout
    html = (tmp_path / "bad" / "report.html").read_text(encoding="utf-8")
    assert 'id="baseline"' in html and "Changes since the baseline run" in html
    assert 'class="chip' in html  # the run's own report, rewritten with the comparison

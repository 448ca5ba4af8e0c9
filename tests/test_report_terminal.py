"""The terminal: live progress on a TTY, plain lines otherwise, and the final table."""

from __future__ import annotations

import io
import re

from rich.console import Console

from conformance.report import Progress, print_final_table
from conformance.suite.verdicts import CaseResult, Level, Verdict

from .test_report_summary import sample_cases, sample_suite

ANSI = re.compile(r"\x1b\[")


def _console(**kwargs) -> Console:
    return Console(file=io.StringIO(), width=120, **kwargs)


def _run(progress: Progress, cases: list[CaseResult]) -> None:
    progress.start(len(cases))
    for case in cases:
        progress.case_started(case.id)
        progress.case_done(case)
    progress.stop()


def test_not_a_tty_prints_one_plain_line_per_non_pass_case():
    console = _console()
    progress = Progress(console)
    assert not progress.live_enabled
    cases = sample_cases()
    _run(progress, cases)
    out = console.file.getvalue()
    lines = out.splitlines()
    assert len(lines) == sum(c.verdict is not Verdict.PASS for c in cases)
    assert not ANSI.search(out)
    assert lines[0].startswith("FAIL          F1-01 [F1, R1] box answered 0000")
    assert "T2-01" not in out and "B3-01" not in out  # PASS cases say nothing
    assert "[bold]markup[/]" in out  # a box's text is never read as markup


def test_quiet_has_no_live_line_even_on_a_tty():
    console = _console(force_terminal=True)
    progress = Progress(console, quiet=True)
    assert not progress.live_enabled
    _run(progress, sample_cases())
    out = console.file.getvalue()
    assert "F1-01" in out and "[8/8]" not in out


def test_live_line_on_a_tty():
    console = _console(force_terminal=True)
    progress = Progress(console)
    assert progress.live_enabled
    cases = sample_cases()
    progress.start(len(cases))
    progress.case_started("F1-01")
    assert "F1-01" in progress.render().plain
    progress.case_done(cases[0])
    progress.case_done(cases[2])
    progress.case_started("A3-02")
    line = progress.render().plain
    assert line.startswith("[2/8]")
    assert "A3-02" in line and "FAIL 1" in line and "PASS 1" in line and "ERROR" not in line
    progress.stop()
    progress.stop()  # twice is harmless
    assert "box answered 0000" in console.file.getvalue()


def test_progress_as_context_manager_stops():
    console = _console(force_terminal=True)
    with Progress(console) as progress:
        progress.start(1)
        assert progress._live is not None
    assert progress._live is None


def test_final_table():
    console = _console()
    cases = sample_cases()
    print_final_table(sample_suite(), cases, console,
                      reports={"HTML report": "out/report.html", "JUnit": "out/junit.xml"})
    out = console.file.getvalue()
    assert "6 of 8 cases did not pass" in out
    for case in cases:
        assert (case.id in out) is (case.verdict is not Verdict.PASS)
    assert out.index("F1-01") < out.index("R5-03") < out.index("A3-02") < out.index("F7-01")  # worst first
    assert "F1, R1" in out and "too many open files" in out
    assert "[bold]markup[/]" in out
    assert "Totals: FAIL 1 · ERROR 1 · NON-STRICT 1 · INCONCLUSIVE 1 · INFORMATIONAL 1 · SKIP 1 · PASS 2" in out
    assert "DOES NOT CONFORM: 1 FAIL, 1 ERROR; 1 NON-STRICT; 1 INCONCLUSIVE (not judged)" in out
    assert "HTML report: out/report.html" in out and "JUnit: out/junit.xml" in out
    assert not ANSI.search(out)


def test_final_table_all_pass_and_paths_list():
    console = _console()
    cases = [CaseResult("B1-01", "ok", ("B1",), Level.MUST, Verdict.PASS)]
    print_final_table(sample_suite(), cases, console, reports=["r/report.html"])
    out = console.file.getvalue()
    assert "All 1 cases passed." in out
    assert "CONFORMS (no FAIL/ERROR); 0 NON-STRICT" in out
    assert "Report: r/report.html" in out
    assert "FAIL 0" in out  # zeros are shown in the totals


def test_final_table_colours_on_a_terminal():
    console = _console(force_terminal=True, color_system="standard")
    print_final_table(sample_suite(), sample_cases(), console)
    assert ANSI.search(console.file.getvalue())

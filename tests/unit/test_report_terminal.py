"""The terminal: live progress on a TTY, plain lines otherwise, and the final table."""

from __future__ import annotations

import io
import re

from rich.console import Console

from conformance.model.verdicts import CaseResult, Level, Verdict
from conformance.report import Progress, print_final_table
from conformance.report.clausetext import clause_text
from conformance.report.terminal import LISTED, NOT_RUN_SHOWN, ROWS_PER_ROOT_CAUSE
from tests.unit.test_report_summary import sample_cases, sample_root_causes, sample_suite

VERDICT_WORDS = tuple(v.value for v in Verdict)

ANSI = re.compile(r"\x1b\[")


def _console(**kwargs) -> Console:
    return Console(file=io.StringIO(), width=120, **kwargs)


def _run(progress: Progress, cases: list[CaseResult]) -> None:
    progress.start(len(cases))
    for case in cases:
        progress.case_started(case.id)
        progress.case_done(case)
    progress.stop()


def test_not_a_tty_prints_no_line_per_case():
    """A CI log holds the final summary only (print_final_table), not a row per INFORMATIONAL or SKIP case."""
    console = _console()
    progress = Progress(console)
    assert not progress.live_enabled
    _run(progress, sample_cases())
    assert console.file.getvalue() == ""


def test_verbose_prints_every_case_with_its_clauses():
    console = _console()
    progress = Progress(console, verbose=True)
    cases = sample_cases()
    _run(progress, cases)
    out = console.file.getvalue()
    lines = out.splitlines()
    case_lines = [line for line in lines if line.startswith(VERDICT_WORDS)]
    assert len(case_lines) == len(cases)  # PASS, INFORMATIONAL and SKIP too
    assert not ANSI.search(out)
    assert lines[0].startswith("FAIL          F1-01 [F1, R1] box answered 0000")
    # each non-PASS case line is followed by the text of the clause(s) its verdict judged
    assert re.match(r"^ {14}R1( \(MUST\))?: " + re.escape(clause_text("R1").text[:40]), lines[1])
    assert all(line.startswith(" " * 14) for line in lines if line not in case_lines)
    assert all(len(line) <= 120 for line in lines if line not in case_lines)  # cut to the console's width
    after_pass = [lines[i + 1] for i, line in enumerate(lines[:-1]) if line.startswith("PASS")]
    assert after_pass and all(line.startswith(VERDICT_WORDS) for line in after_pass)  # no clause text under a PASS
    assert "T2-01" in out and "B3-01" in out
    assert "[bold]markup[/]" in out  # a box's text is never read as markup


def test_quiet_has_no_live_line_and_no_line_per_case_even_on_a_tty():
    console = _console(force_terminal=True)
    progress = Progress(console, quiet=True)
    assert not progress.live_enabled
    _run(progress, sample_cases())
    out = console.file.getvalue()
    assert "F1-01" not in out and "[8/8]" not in out


def test_a_tty_shows_the_listed_verdicts_as_they_finish_not_informational_or_skip():
    console = _console(force_terminal=True)
    cases = sample_cases()
    with Progress(console) as progress:
        for case in cases:
            progress.case_done(case)
    out = console.file.getvalue()
    for case in cases:
        assert (case.id in out) is (case.verdict in LISTED), case.id


def test_final_table():
    console = Console(file=io.StringIO(), width=160)
    cases = sample_cases()
    print_final_table(sample_suite(), cases, console,
                      reports={"HTML report": "out/report.html", "JUnit": "out/junit.xml"})
    out = console.file.getvalue()
    assert "4 of 8 cases FAIL, ERROR, NON-STRICT or INCONCLUSIVE; 1 INFORMATIONAL and 1 SKIP counted, not listed" in out
    for case in cases:
        assert (case.id in out) is (case.verdict in LISTED)
    assert out.index("F1-01") < out.index("R5-03") < out.index("A3-02") < out.index("S2-01")  # worst first
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


def test_a_long_report_path_stays_on_one_line_at_80_columns():
    path = "/tmp/pytest-of-someone/pytest-307/popen-gw1/test_a_clean_capture_exits_0_w0/r/report.html"
    lines = _lines_at_80(suite=sample_suite(), cases=sample_cases(), reports={"HTML report": path})
    assert f"HTML report: {path}" in lines  # whole, so it can be copied from the terminal
    _check_80([line for line in lines if path not in line])


def test_final_table_colours_on_a_terminal():
    console = _console(force_terminal=True, color_system="standard")
    print_final_table(sample_suite(), sample_cases(), console)
    assert ANSI.search(console.file.getvalue())


def _lines_at_80(**kwargs) -> list[str]:
    console = Console(file=io.StringIO(), width=80)
    print_final_table(console=console, **kwargs)
    return console.file.getvalue().splitlines()


def _check_80(lines: list[str]) -> None:
    for line in lines:
        assert len(line) <= 80, line
        assert len(line.split()) != 1, f"a lone word on a line: {line!r}"


def test_final_table_at_80_columns_cuts_never_wraps():
    long = CaseResult("R1-11[tcp-robot-to-box-tc17-with-a-long-name]", "t", ("A1", "A4", "B1", "B2", "B3", "B4", "B5"),
                      Level.MUST, Verdict.FAIL, message="A5: a frame that is not a request MUST NOT be answered 0000: "
                      "expected did not answer 0000 (silence, a non-zero error, or a close); the box sent " * 3)
    lines = _lines_at_80(suite=sample_suite(), cases=[*sample_cases(), long], reports={"HTML report": "r/report.html"})
    _check_80(lines)
    row = next(line for line in lines if "R1-11" in line)
    assert row.rstrip().endswith("…")  # the message is cut
    assert re.search(r"R1-11\[tcp-robot-to-box-\S*… +A1, A4, B1,?… +A5: a frame that is", row)  # id, clauses cut
    assert sum(1 for line in lines if "R1-11" in line) == 1
    assert any(line.startswith("DOES NOT CONFORM: 2 FAIL, 1 ERROR;") for line in lines)
    assert any("INCONCLUSIVE (not judged)" in line for line in lines)


def test_final_table_root_causes_lead_and_group_rows():
    cases, rcs = sample_root_causes()
    lines = _lines_at_80(suite=sample_suite(), cases=cases, root_causes=rcs)
    _check_80(lines)
    out = "\n".join(lines)
    assert lines[0] == "Root causes (1), in the order to fix them:"
    assert lines[1].startswith("  RC1 [F2, A2] every answer carries version 01 00 instead of 00 01 (14 cases)")
    assert clause_text("F2").text[:30] in lines[2]
    group = out.index("RC1: every answer carries version 01 00 instead of 00 01 (14)")
    assert out.index("Root causes") < group < out.index("A5-01[v00]") < out.index("Not explained by a root cause (4)")
    assert f"… and {14 - ROWS_PER_ROOT_CAUSE} more explained by RC1" in out
    assert f"A5-01[v{ROWS_PER_ROOT_CAUSE:02d}]" not in out and "A3-01[g0]" not in out  # beyond the cap
    rest = out[out.index("Not explained by a root cause"):]
    for cid in ("F1-01", "R5-03", "A3-02", "S2-01"):
        assert cid in rest


def test_final_table_incomplete_run_lists_cases_not_run():
    not_run = [f"R2-{i:02d}" for i in range(25)]
    suite = sample_suite(complete=False, cases_total=33, not_run=not_run)
    lines = _lines_at_80(suite=suite, cases=sample_cases())
    _check_80(lines)
    out = "\n".join(lines)
    assert "INCOMPLETE (8 of 33 cases run): DOES NOT CONFORM so far: 1 FAIL, 1 ERROR;" in out
    assert "CONFORMS (no" not in out
    assert "Not run (25): R2-00, R2-01," in out
    assert f"R2-{NOT_RUN_SHOWN - 1:02d}, … and {25 - NOT_RUN_SHOWN} more" in out
    assert f"R2-{NOT_RUN_SHOWN:02d}" not in out


def test_final_table_counts_informational_and_skip_only():
    cases = [CaseResult("B1-01", "ok", ("B1",), Level.MUST, Verdict.PASS),
             CaseResult("F7-01", "udp", ("F7",), Level.MUST, Verdict.SKIP, message="no --udp-target"),
             CaseResult("S3-02", "info", ("S3",), Level.MAY, Verdict.INFORMATIONAL, message="answered 0002")]
    lines = _lines_at_80(suite=sample_suite(), cases=cases)
    out = "\n".join(lines)
    assert "F7-01" not in out and "S3-02" not in out
    assert "No case FAIL, ERROR, NON-STRICT or INCONCLUSIVE among 3." in out
    assert "INFORMATIONAL 1 · SKIP 1 · PASS 1" in " ".join(out.split())


def test_a_log_gets_a_plain_progress_line_at_the_interval(monkeypatch):
    """A long run's log is never silent for long: a plain progress line per interval (here: every case)."""
    import conformance.report.terminal as terminal

    monkeypatch.setattr(terminal, "PLAIN_PROGRESS_EVERY_S", 0.0)
    console = _console()
    cases = sample_cases()
    _run(Progress(console), cases)
    lines = console.file.getvalue().splitlines()
    assert len(lines) == len(cases) and lines[-1].startswith(f"[{len(cases)}/{len(cases)}] "), lines
    assert not any(line.startswith(VERDICT_WORDS) for line in lines)

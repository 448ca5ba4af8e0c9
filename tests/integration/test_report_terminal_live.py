"""The live progress line on a terminal (rich's Live refreshes it from a thread); the rest of the
terminal output is in tests/unit/test_report_terminal.py."""

from __future__ import annotations

from conformance.report import Progress
from tests.unit.test_report_summary import sample_cases
from tests.unit.test_report_terminal import _console


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

"""Report writers: summary.json, junit.xml, report.html, latency SVGs and the terminal.

Every writer derives its totals, clause verdicts and overall line from
:mod:`.summary`, so the reports agree with each other. Files are written atomically.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

from ..model.verdicts import CaseResult, RootCause, SuiteInfo
from .diff import RunDiff
from .html import render_html, write_html
from .junit import write_junit
from .run_comparison import Baseline
from .summary import by_clause, conforms, overall_line, totals, write_summary
from .svg import latency_svg
from .terminal import Progress, print_final_table

__all__ = [
    "Progress",
    "by_clause",
    "conforms",
    "latency_svg",
    "overall_line",
    "print_final_table",
    "render_html",
    "totals",
    "write_html",
    "write_junit",
    "write_reports",
    "write_summary",
]


def write_reports(report_dir: Path, suite: SuiteInfo, cases: list[CaseResult],
                  root_causes: Sequence[RootCause] = (), baseline: Baseline | None = None) -> RunDiff | None:
    """summary.json, junit.xml and report.html into ``report_dir``, each written atomically; with a
    ``baseline`` (``run --baseline``), report.html holds the comparison, which is returned."""
    report_dir.mkdir(parents=True, exist_ok=True)
    summary = write_summary(report_dir / "summary.json", suite, cases, root_causes)
    diff = baseline.compare(summary, report_dir / "summary.json") if baseline is not None else None
    write_junit(report_dir / "junit.xml", suite, cases, root_causes)
    write_html(report_dir / "report.html", suite, cases, root_causes=root_causes, diff=diff)
    return diff

"""Report writers: summary.json, junit.xml, report.html, latency SVGs and the terminal.

Every writer derives its totals, clause verdicts and overall line from
:mod:`.summary`, so the reports agree with each other. Files are written atomically.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any

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


def packaged(cases: Sequence[CaseResult], report_dir: Path) -> list[CaseResult]:
    """The cases with their pcap paths as the package holds them: relative to ``report_dir`` (``pcaps/X.pcapng``)
    when the pcap is inside it, so moving or zipping the directory keeps every link; absolute when it is not
    (``--pcap-dir`` elsewhere, or the top-level ``pcaps/`` of a run without ``--report-dir``)."""
    return [replace(case, pcap=package_path(case.pcap, report_dir)) if case.pcap else case for case in cases]


def package_path(path: str, report_dir: Path) -> str:
    """``path`` (relative to the current directory, or absolute) as the package names it: relative to
    ``report_dir`` when inside it, else absolute."""
    root, where = os.path.abspath(report_dir), os.path.abspath(path)
    inside = os.path.commonpath([root, where]) == root
    return Path(os.path.relpath(where, root)).as_posix() if inside else where


def _packaged_acceptance(acceptance: dict[str, Any] | None, report_dir: Path,
                         cases: Sequence[CaseResult]) -> dict[str, Any] | None:
    """The acceptance with its rows' pcaps named as the package holds them, and the folders of the pcaps that
    lie outside the package (``--pcap-dir`` elsewhere, or a run without ``--report-dir``): its manifest does not
    cover them, and the report says so."""
    if acceptance is None:
        return None
    rows = [{**row, "pcap": package_path(row["pcap"], report_dir) if row.get("pcap") else row.get("pcap")}
            for row in acceptance.get("declared_observed") or []]
    outside = sorted({os.path.dirname(c.pcap) for c in cases if c.pcap and os.path.isabs(c.pcap)})
    return {**acceptance, "declared_observed": rows, "outside_package": outside}


def write_reports(report_dir: Path, suite: SuiteInfo, cases: list[CaseResult],
                  root_causes: Sequence[RootCause] = (), baseline: Baseline | None = None,
                  acceptance: dict[str, Any] | None = None) -> RunDiff | None:
    """summary.json, junit.xml and report.html into ``report_dir``, each written atomically; with a
    ``baseline`` (``run --baseline``), report.html holds the comparison, which is returned. ``acceptance``
    (:meth:`conformance.acceptance.record.Acceptance.to_dict`): the run ID, the device under test, the tester
    and the declared / observed table, in summary.json and on report.html's first page. Pcap paths are written
    relative to ``report_dir`` when the pcaps are inside it (:func:`packaged`)."""
    report_dir.mkdir(parents=True, exist_ok=True)
    cases = packaged(cases, report_dir)
    acceptance = _packaged_acceptance(acceptance, report_dir, cases)
    summary = write_summary(report_dir / "summary.json", suite, cases, root_causes, acceptance=acceptance)
    diff = baseline.compare(summary, report_dir / "summary.json") if baseline is not None else None
    write_junit(report_dir / "junit.xml", suite, cases, root_causes, acceptance)
    write_html(report_dir / "report.html", suite, cases, pcap_base=report_dir, root_causes=root_causes, diff=diff,
               acceptance=acceptance)
    return diff

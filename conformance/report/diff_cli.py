"""``isight-conformance diff OLD NEW`` and ``run --baseline OLD``.

``diff`` compares two runs (each a summary.json or the report directory holding one).
Exit status: 0 nothing got worse, 1 something did (a new FAIL, ERROR or NON-STRICT),
2 a path that is missing, unreadable or not a summary.json (one line on stderr).

``run --baseline OLD``: :func:`apply_baseline` compares the run just written with OLD,
prints the comparison under the final table and writes it into report.html.
"""

from __future__ import annotations

import argparse
import os
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

from rich.console import Console
from rich.text import Text

from ..i18n import _
from ..model.verdicts import CaseResult
from .diff import RunDiff, compare, render, render_text
from .load import SummaryError, load_summary, root_causes_of, suite_of, summary_path

if TYPE_CHECKING:
    from ..options import Subparsers

EXIT_SAME, EXIT_WORSE, EXIT_USAGE = 0, 1, 2


def add_parser(sub: Subparsers) -> argparse.ArgumentParser:
    p = sub.add_parser(
        "diff",
        help=_("compare two runs (summary.json files or report directories): what got worse, what got better"),
        description=_("Compare two runs of the suite, e.g. before and after a firmware upgrade. OLD and NEW are "
        "summary.json files or the report directories holding them. Lists what got worse (a new FAIL, ERROR or "
        "NON-STRICT), what got better, other verdict changes, cases added or removed, with each case's clauses. "
        "Exit status: 0 nothing got worse, 1 something did, 2 a path that is missing or not a summary.json."),
    )
    p.add_argument("old", metavar="OLD", help=_("the earlier run: summary.json or its report directory"))
    p.add_argument("new", metavar="NEW", help=_("the later run: summary.json or its report directory"))
    p.add_argument("--format", choices=("text", "json", "markdown"), default="text",
                   help=_("text (default), json, or markdown (for a CI comment)"))
    p.add_argument("-o", "--output", metavar="FILE", help=_("write the comparison to FILE as well as to stdout"))
    p.set_defaults(func=main_diff)
    return p


def main_diff(args: argparse.Namespace) -> int:
    try:
        old, new = load_summary(args.old), load_summary(args.new)
    except SummaryError as exc:
        print(f"isight-conformance diff: {exc}", file=sys.stderr)
        return EXIT_USAGE
    diff = compare(old, new, os.fspath(args.old), os.fspath(args.new))
    text = render(diff, args.format)
    if args.output:
        from .summary import atomic_write_bytes

        try:
            atomic_write_bytes(args.output, text.encode("utf-8", "backslashreplace"))
        except OSError as exc:
            print(f"isight-conformance diff: cannot write {args.output}: {exc.strerror or exc}", file=sys.stderr)
            return EXIT_USAGE
    sys.stdout.write(text)
    return EXIT_WORSE if diff.got_worse else EXIT_SAME


def load_baseline(path: str | os.PathLike[str] | None) -> dict[str, Any] | None:
    """The baseline summary for ``run --baseline`` (None without one). Raises
    :class:`SummaryError` (a ValueError, one line) so the run stops before it starts."""
    return None if path is None else load_summary(path)


def apply_baseline(baseline: dict[str, Any] | None, report_dir: Path, cases: Sequence[CaseResult],
                   console: Console | None = None, baseline_label: str = "baseline") -> RunDiff | None:
    """After a run: compare report_dir/summary.json with the baseline, print the comparison
    and write report.html again with it (the run's own cases keep their wire logs)."""
    if baseline is None:
        return None
    console = console or Console()
    try:
        new = load_summary(report_dir)
    except SummaryError as exc:
        console.print(Text(_("No comparison with the baseline: {reason}").format(reason=exc), style="yellow"))
        return None
    diff = compare(baseline, new, baseline_label, os.fspath(summary_path(report_dir)))
    console.print(Text(_("Compared with the baseline {label}:").format(label=baseline_label), style="bold"))
    console.print(Text(render_text(diff)), soft_wrap=True)
    from .html import write_html

    write_html(report_dir / "report.html", suite_of(new), list(cases), root_causes=root_causes_of(new), diff=diff)
    return diff

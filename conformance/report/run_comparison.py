"""``run --baseline OLD``: the earlier run the reports compare this one with.

:func:`load_baseline` reads OLD before the run starts (a bad one stops it with one line);
:func:`~conformance.report.write_reports` compares the summary it writes with it and writes
report.html once, with the comparison; :func:`print_comparison` shows it under the final table.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from rich.console import Console
from rich.text import Text

from ..i18n import _
from .diff import RunDiff, compare, render_text
from .load import load_summary


@dataclass(frozen=True)
class Baseline:
    """An earlier run's summary.json, as loaded, and how the comparison names it (the path given)."""

    doc: dict[str, Any]
    label: str = "baseline"

    def compare(self, summary: dict[str, Any], summary_file: Path) -> RunDiff:
        """What changed from the baseline to ``summary`` (the document just written to ``summary_file``)."""
        return compare(self.doc, summary, self.label, os.fspath(summary_file))


def load_baseline(path: str | os.PathLike[str] | None) -> Baseline | None:
    """The baseline for ``run --baseline`` (None without one). Raises
    :class:`~conformance.report.load.SummaryError` (a ValueError, one line) so the run stops before it starts."""
    return None if path is None else Baseline(load_summary(path), os.fspath(path))


def print_comparison(baseline: Baseline | None, diff: RunDiff | None, console: Console | None = None) -> None:
    """Under the final table: the comparison with the baseline, or why there is none."""
    if baseline is None:
        return
    console = console or Console()
    if diff is None:
        console.print(Text(_("No comparison with the baseline: {reason}").format(reason="no summary.json was written"),
                           style="yellow"))
        return
    console.print(Text(_("Compared with the baseline {label}:").format(label=baseline.label), style="bold"))
    console.print(Text(render_text(diff)), soft_wrap=True)

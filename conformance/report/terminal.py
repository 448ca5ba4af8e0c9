"""What the terminal shows while the suite runs and after it.

* :class:`Progress`: on a TTY, one live line (cases done/total, the current case,
  counts by verdict so far), with each non-PASS case printed above it as it finishes.
  With ``quiet=True`` or when the console is not a terminal (CI logs, pipes) there is
  no live line, only one plain line per non-PASS case.
* :func:`print_final_table`: the non-PASS cases, the totals, the overall line and
  where the reports were written.
"""

from __future__ import annotations

import os
import time
from collections.abc import Iterable, Mapping, Sequence

from rich.console import Console, Group
from rich.live import Live
from rich.table import Table
from rich.text import Text

from ..suite.verdicts import VERDICT_ORDER, CaseResult, RootCause, SuiteInfo, Verdict
from .summary import format_duration, one_line, overall_line, overall_state, rank, totals

STYLES: dict[Verdict, str] = {
    Verdict.PASS: "green",
    Verdict.NON_STRICT: "yellow",
    Verdict.INFORMATIONAL: "blue",
    Verdict.INCONCLUSIVE: "cyan",
    Verdict.SKIP: "dim",
    Verdict.FAIL: "bold red",
    Verdict.ERROR: "bold magenta",
}
OVERALL_STYLES = {"conforms": "bold green", "fails": "bold red", "unjudged": "bold yellow", "incomplete": "bold yellow"}


def verdict_counts_text(counts: Mapping[str, int], zeros: bool = False) -> Text:
    """``FAIL 2 · NON-STRICT 1 · PASS 40`` (worst first), coloured."""
    text = Text()
    for v in VERDICT_ORDER:
        n = counts.get(v.value, 0)
        if not n and not zeros:
            continue
        if text:
            text.append(" · ", style="dim")
        text.append(f"{v.value} {n}", style=STYLES[v] if n else "dim")
    return text


def case_line(result: CaseResult) -> Text:
    """One plain line for a finished case: verdict, id, clauses, message."""
    line = Text()
    line.append(f"{result.verdict.value:<13}", style=STYLES[result.verdict])
    line.append(f" {result.id}", style="bold")
    if result.clauses:
        line.append(f" [{', '.join(result.clauses)}]", style="dim")
    if result.message:
        line.append(f" {one_line(result.message, 300)}")
    return line


class Progress:
    """Live progress of a run: ``start(total)``, ``case_started(id)`` (optional),
    ``case_done(result)`` for each case, ``stop()``. Also a context manager."""

    def __init__(self, console: Console | None = None, quiet: bool = False) -> None:
        self.console = console or Console()
        self.live_enabled = not quiet and self.console.is_terminal and not self.console.is_dumb_terminal
        self.total = 0
        self.done = 0
        self.current = ""
        self.counts = {v.value: 0 for v in VERDICT_ORDER}
        self._started = 0.0
        self._live: Live | None = None

    # -- lifecycle ----------------------------------------------------------------
    def start(self, total: int) -> None:
        self.total, self.done, self._started = max(0, int(total)), 0, time.monotonic()
        self.counts = {v.value: 0 for v in VERDICT_ORDER}
        if self.live_enabled and self._live is None:
            self._live = Live(console=self.console, get_renderable=self.render, refresh_per_second=8,
                              transient=True, redirect_stdout=False, redirect_stderr=False)
            self._live.start()

    def case_started(self, case_id: str) -> None:
        self.current = case_id
        self._refresh()

    def case_done(self, result: CaseResult) -> None:
        self.done += 1
        self.counts[result.verdict.value] += 1
        self.current = result.id
        if result.verdict is not Verdict.PASS:
            # above the live line on a TTY; the only output otherwise
            self.console.print(case_line(result), soft_wrap=True, highlight=False)
        self._refresh()

    def stop(self) -> None:
        if self._live is not None:
            self._live.stop()
            self._live = None

    def __enter__(self) -> Progress:
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()

    # -- display ------------------------------------------------------------------
    def render(self) -> Text:
        """The live line."""
        line = Text()
        width = len(str(self.total or self.done))
        total = str(self.total) if self.total else "?"
        line.append(f"[{self.done:>{width}}/{total}] ", style="bold")
        line.append(format_duration(time.monotonic() - self._started) + " ", style="dim")
        if self.current:
            line.append(f"{self.current}  ", style="bold cyan")
        line.append_text(verdict_counts_text(self.counts))
        line.no_wrap = True
        line.overflow = "ellipsis"
        return line

    def _refresh(self) -> None:
        if self._live is not None:
            self._live.refresh()


def print_final_table(suite: SuiteInfo, cases: list[CaseResult], console: Console | None = None,
                      reports: Mapping[str, str | os.PathLike[str]] | Iterable[str | os.PathLike[str]] | None = None,
                      root_causes: Sequence[RootCause] = ()) -> None:
    """The end of a run: the root causes, a table of every non-PASS case (worst first), totals
    by verdict, the overall line, and the reports written (``{"HTML report": path, ...}`` or paths)."""
    console = console or Console()
    failing = sorted((c for c in cases if c.verdict is not Verdict.PASS), key=lambda c: rank(c.verdict))
    parts: list[Text | Table] = []
    for cause in root_causes:
        line = Text()
        line.append(f"{cause.id} ", style="bold red")
        line.append(f"[{', '.join(cause.clauses)}] ", style="dim")
        line.append(f"{cause.title} (explains {len(cause.cases)} cases)")
        parts.append(line)
    if failing:
        table = Table(title=f"{len(failing)} of {len(cases)} cases did not pass", title_justify="left",
                      show_lines=False, expand=False, header_style="bold")
        table.add_column("Case", no_wrap=True)
        table.add_column("Verdict", no_wrap=True)
        table.add_column("Clauses", no_wrap=True)
        table.add_column("Message", overflow="fold")
        for c in failing:
            # Text, never str: rich would read "[...]" in a box's message as markup
            table.add_row(Text(one_line(c.id, 120)), Text(c.verdict.value, style=STYLES[c.verdict]),
                          Text(", ".join(c.clauses)), Text(one_line(c.message, 400)))
        parts.append(table)
    elif cases:
        parts.append(Text(f"All {len(cases)} cases passed.", style="green"))
    line = Text()
    line.append("Totals: ", style="bold")
    line.append_text(verdict_counts_text(totals(cases), zeros=True))
    line.append(f"  ({len(cases)} cases, {format_duration(suite.duration_s)})", style="dim")
    parts.append(line)
    parts.append(Text(overall_line(cases, suite), style=OVERALL_STYLES[overall_state(cases, suite)]))
    parts.append(Text(f"Target: {suite.target}", style="dim"))
    if reports:
        items = reports.items() if isinstance(reports, Mapping) else ((None, p) for p in reports)
        for label, path in items:
            out = Text()
            out.append("Report: " if label is None else f"{label}: ", style="bold")
            out.append(os.fspath(path))
            parts.append(out)
    console.print(Group(*parts), soft_wrap=False)

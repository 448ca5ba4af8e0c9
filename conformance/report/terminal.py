"""What the terminal shows while the suite runs and after it.

* :class:`Progress`: on a TTY, one live line (cases done/total, the current case,
  counts by verdict so far), with each FAIL, ERROR, NON-STRICT and INCONCLUSIVE case
  printed above it as it finishes. With ``quiet=True`` or when the console is not a
  terminal (CI logs, pipes) there is no live line and no line per case, only a plain
  progress line once a minute: the log holds the same final summary a person sees at a
  terminal. ``verbose=True`` prints every case as it finishes, PASS included.
  Each printed non-PASS case line is followed by the text of the clause(s) the verdict judged.
* :func:`print_final_table`: the root causes first, then the FAIL, ERROR, NON-STRICT and
  INCONCLUSIVE cases grouped by root cause (INFORMATIONAL and SKIP only counted), the
  totals, the overall line (INCOMPLETE with the cases not run for a run cut short) and
  where the reports were written. Every row is one line at any width: long ids, clause
  lists and messages are cut with an ellipsis, never wrapped.
"""

from __future__ import annotations

import os
import time
from collections.abc import Iterable, Mapping, Sequence

from rich.console import Console, Group
from rich.live import Live
from rich.table import Table
from rich.text import Text

from ..i18n import LEVEL_NAMES, N_, _, ngettext
from ..model.verdicts import VERDICT_ORDER, CaseResult, RootCause, SuiteInfo, Verdict
from .clausetext import clause_text, judged_texts
from .summary import format_duration, one_line, overall_line, overall_state, rank, totals

#: the verdicts the final table lists, one row each (INFORMATIONAL and SKIP are counted)
LISTED = (Verdict.FAIL, Verdict.ERROR, Verdict.NON_STRICT, Verdict.INCONCLUSIVE)
ROWS_PER_ROOT_CAUSE = 10  # rows shown under a root cause; the rest are counted
NOT_RUN_SHOWN = 10  # ids of cases not run shown for an incomplete run
#: without a live line, a plain progress line at most this often (a CI log is never silent for long)
PLAIN_PROGRESS_EVERY_S = 60.0

STYLES: dict[Verdict, str] = {
    Verdict.PASS: "green",
    Verdict.NON_STRICT: "yellow",
    Verdict.INFORMATIONAL: "blue",
    Verdict.INCONCLUSIVE: "cyan",
    Verdict.SKIP: "dim",
    Verdict.FAIL: "bold red",
    Verdict.ERROR: "bold magenta",
}
#: the labels of the reports a run lists at its end (translated where shown)
REPORT_LABELS = (N_("HTML report"), N_("JSON summary"), N_("JUnit"), N_("pcaps"), N_("manifest"), N_("manifest sha256"))
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


def level_words(level: str) -> str:
    """``MUST/SHOULD`` in the active language, short (``应/宜``): the clause line is cut to the terminal's width."""
    return "/".join(_(LEVEL_NAMES[w]) if w in LEVEL_NAMES else w for w in level.split("/"))


def clause_lines(result: CaseResult, width: int = 240, indent: str = "              ") -> Text:
    """The text of the clause(s) a non-PASS verdict judged, one dim line each, cut to ``width``."""
    out = Text(style="dim")
    for i, t in enumerate(judged_texts(result)):
        if i:
            out.append("\n")
        out.append(indent + one_line(f"{t.id}{f' ({level_words(t.level)})' if t.level else ''}: {t.text}",
                                     max(width - len(indent), 30)))
    return out


class Progress:
    """Live progress of a run: ``start(total)``, ``case_started(id)`` (optional),
    ``case_done(result)`` for each case, ``stop()``. Also a context manager."""

    def __init__(self, console: Console | None = None, quiet: bool = False, verbose: bool = False) -> None:
        self.console = console or Console()
        self.live_enabled = not quiet and self.console.is_terminal and not self.console.is_dumb_terminal
        self.verbose = verbose
        self._plain_at = 0.0
        self.total = 0
        self.done = 0
        self.current = ""
        self.counts = {v.value: 0 for v in VERDICT_ORDER}
        self._started = 0.0
        self._live: Live | None = None

    # -- lifecycle ----------------------------------------------------------------
    def start(self, total: int) -> None:
        self.total, self.done, self._started = max(0, int(total)), 0, time.monotonic()
        self._plain_at = self._started
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
        if self.verbose or (self.live_enabled and result.verdict in LISTED):
            self.print_case(result)  # above the live line on a TTY
        elif not self.live_enabled and time.monotonic() - self._plain_at >= PLAIN_PROGRESS_EVERY_S:
            self._plain_at = time.monotonic()
            self.console.print(self.render().plain, soft_wrap=True, highlight=False)
        self._refresh()

    def print_case(self, result: CaseResult) -> None:
        """The case's line; for a non-PASS case, the text of the clause(s) its verdict judged under it."""
        self.console.print(case_line(result), soft_wrap=True, highlight=False)
        texts = clause_lines(result, self.console.width) if result.verdict is not Verdict.PASS else Text()
        if texts:
            self.console.print(texts, soft_wrap=True, highlight=False)

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


def packed(segments: Sequence[str], width: int, style: str = "", indent: str = "  ") -> Text:
    """``segments`` joined on as few lines as fit ``width``, broken only between segments
    (a verdict count, a clause of the overall line): never one word left alone on a line."""
    lines: list[str] = []
    for seg in segments:
        if lines and len(lines[-1]) + 1 + len(seg) <= width:
            lines[-1] += " " + seg
        else:
            lines.append(seg if not lines else indent + seg)
    return Text("\n".join(lines), style=style)


def _case_table(rows: Sequence[CaseResult], title: str | None = None) -> Table:
    """One line per case at any width: id, clauses and message cut with an ellipsis."""
    table = Table(title=title, title_justify="left", title_style="bold", box=None, padding=(0, 1),
                  show_header=True, header_style="bold", expand=True)
    table.add_column(_("Verdict"), no_wrap=True, width=12)
    table.add_column(_("Case"), no_wrap=True, overflow="ellipsis", max_width=24)
    table.add_column(_("Clauses"), no_wrap=True, overflow="ellipsis", max_width=11)
    table.add_column(_("Message"), no_wrap=True, overflow="ellipsis", ratio=1, min_width=28)
    for c in rows:
        # Text, never str: rich would read "[...]" in a box's message as markup
        table.add_row(Text(c.verdict.value, style=STYLES[c.verdict]), Text(one_line(c.id, 120)),
                      Text(", ".join(c.clauses)), Text(one_line(c.message or c.title, 400)))
    return table


def _root_cause_lines(root_causes: Sequence[RootCause], cases: Sequence[CaseResult]) -> list[Text]:
    present = {c.id for c in cases}
    lines = [Text(_("Root causes ({n}), in the order to fix them:").format(n=len(root_causes)), style="bold")]
    for rc in root_causes:
        line = Text("  ")
        line.append(rc.id, style="bold red" if rc.level.value == "MUST" else "bold yellow")
        line.append(f" [{', '.join(rc.clauses)}] ", style="dim")
        line.append(one_line(rc.title, 200))
        n = sum(1 for cid in rc.cases if cid in present) or len(rc.cases)
        line.append(" " + ngettext("({n} case)", "({n} cases)", n).format(n=n), style="dim")
        line.no_wrap, line.overflow = True, "ellipsis"
        lines.append(line)
        for cid in rc.clauses[:2]:
            t = clause_text(cid)
            text = Text(f"      {cid}: {one_line(t.text, 300)}", style="dim")
            text.no_wrap, text.overflow = True, "ellipsis"
            lines.append(text)
        proof = proof_line(rc)
        if proof:
            text = Text(f"      {proof}", style="dim")
            text.no_wrap, text.overflow = True, "ellipsis"
            lines.append(text)
    return lines


def proof_line(rc: RootCause) -> str:
    """How the diagnose phase settled a root cause: the experiment that confirmed it and the repro file, or
    that none did ("" when no diagnosis ran)."""
    d = rc.diagnosis
    if not d:
        return ""
    repro = (d.get("repro") or {}).get("file", "")
    ruled_out = sum(1 for h in d.get("hypotheses", []) if h.get("status") == "ruled out")
    if not d.get("confirmed"):
        return _("no experiment confirmed it ({n} other stories ruled out)").format(n=ruled_out)
    found = next((h for h in d.get("hypotheses", []) if h.get("status") == "confirmed" and h.get("key") != "catalogue"),
                 None)
    where = found.get("experiment", "") if found else "session"
    line = _("confirmed by experiment '{name}', {n} other stories ruled out").format(name=where, n=ruled_out)
    return line + (_("; repro: {file} (replay it after a fix)").format(file=repro) if repro else "")


def print_final_table(suite: SuiteInfo, cases: list[CaseResult], console: Console | None = None,
                      reports: Mapping[str, str | os.PathLike[str]] | Iterable[str | os.PathLike[str]] | None = None,
                      root_causes: Sequence[RootCause] = ()) -> None:
    """The end of a run: the root causes, a table of the FAIL, ERROR, NON-STRICT and
    INCONCLUSIVE cases (grouped by root cause, worst first), totals by verdict, the
    overall line, the cases not run, and the reports written (``{"HTML report": path, ...}`` or paths)."""
    console = console or Console()
    listed = sorted((c for c in cases if c.verdict in LISTED), key=lambda c: rank(c.verdict))
    t = totals(cases)
    parts: list[Text | Table] = []
    known = {rc.id for rc in root_causes}
    if root_causes:
        parts += _root_cause_lines(root_causes, cases)
    if listed:
        counted = _(" and ").join(f"{t[v.value]} {v.value}" for v in (Verdict.INFORMATIONAL, Verdict.SKIP) if t[v.value])
        parts.append(packed([_("{listed} of {n} cases FAIL, ERROR, NON-STRICT or INCONCLUSIVE").format(
                                 listed=len(listed), n=len(cases)) + (";" if counted else ""),
                             *([_("{counted} counted, not listed").format(counted=counted)] if counted else [])],
                            console.width, "bold"))
        for rc in root_causes:
            rows = [c for c in listed if c.root_cause == rc.id]
            if rows:
                parts.append(_case_table(rows[:ROWS_PER_ROOT_CAUSE], f"{rc.id}: {one_line(rc.title, 160)} ({len(rows)})"))
                if len(rows) > ROWS_PER_ROOT_CAUSE:
                    parts.append(Text("  " + _("… and {more} more explained by {id} (see report.html)").format(
                        more=len(rows) - ROWS_PER_ROOT_CAUSE, id=rc.id), style="dim"))
        rest = [c for c in listed if c.root_cause not in known]
        if rest:
            parts.append(_case_table(rest, _("Not explained by a root cause ({n})").format(n=len(rest))
                                     if root_causes else None))
    elif cases:
        not_pass = len(cases) - t[Verdict.PASS.value]
        parts.append(Text(_("All {n} cases passed.").format(n=len(cases)) if not not_pass else
                          _("No case FAIL, ERROR, NON-STRICT or INCONCLUSIVE among {n}.").format(n=len(cases)),
                          style="green"))
    counts = [f"{v.value} {t[v.value]} ·" for v in VERDICT_ORDER]
    totals_word = _("Totals:")
    line = packed([totals_word, *counts[:-1], counts[-1].rstrip(" ·"),
                   _(" ({n} cases, {duration})").format(n=len(cases), duration=format_duration(suite.duration_s))],
                  console.width)
    line.highlight_words([totals_word], style="bold")
    for v in VERDICT_ORDER:
        line.highlight_regex(rf"{v.value} [1-9]\d*", style=STYLES[v])
    parts.append(line)
    overall = overall_line(cases, suite)
    parts.append(packed([seg + ";" for seg in overall.split("; ")[:-1]] + overall.split("; ")[-1:], console.width,
                        OVERALL_STYLES[overall_state(cases, suite)]))
    if not suite.complete and suite.not_run:
        more = len(suite.not_run) - NOT_RUN_SHOWN
        ids = [f"{cid}," for cid in suite.not_run[:NOT_RUN_SHOWN]]
        ids[-1] = ids[-1].rstrip(",") + (_(", … and {more} more").format(more=more) if more > 0 else "")
        parts.append(packed([_("Not run ({n}):").format(n=len(suite.not_run)), *ids], console.width, "yellow"))
    parts.append(Text(_("Target: {target}").format(target=suite.target), style="dim"))
    console.print(Group(*parts), soft_wrap=False)
    if reports:  # a path stays on one line at any width, so it can be copied whole
        items = reports.items() if isinstance(reports, Mapping) else ((None, p) for p in reports)
        for label, path in items:
            out = Text()
            out.append(_("Report: ") if label is None else f"{_(label)}: ", style="bold")
            out.append(os.fspath(path))
            console.print(out, soft_wrap=True)

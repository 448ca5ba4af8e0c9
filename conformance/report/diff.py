"""Comparing two runs: what changed since the last firmware (pure; no files, no clock).

:func:`compare` takes two parsed summary.json documents (OLD, NEW) and sorts every case:

* **worse**: NEW's verdict is FAIL, ERROR or NON-STRICT and worse than OLD's (or the
  case is new): ``PASS → FAIL``, ``NON-STRICT → FAIL``, ``(new) → NON-STRICT``...
* **better**: OLD's verdict was FAIL, ERROR or NON-STRICT and NEW's is better.
* **changed**: any other change of verdict (``PASS → INCONCLUSIVE``, ``SKIP → PASS``...).
* **added** / **removed**: cases only NEW / only OLD has (a different suite version or
  selection); cases NEW did not reach because it was cut short are **not run**, not removed.

It also notes what makes the two runs hard to compare (profile settings, suite or clause
registry version, target) and the root causes that appeared or went away. Renderers give
the comparison as text (the terminal), Markdown (a CI comment) or JSON.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field
from typing import Any

from ..i18n import N_, _
from ..model.verdicts import Verdict
from .load import cases_of, suite_of
from .summary import one_line, overall_line, rank

BAD = (Verdict.FAIL, Verdict.ERROR, Verdict.NON_STRICT)
MARKDOWN_ROWS = 60  # rows per section in a Markdown comment (CI comments are size-limited)


@dataclass(frozen=True)
class Change:
    id: str
    clauses: tuple[str, ...]
    title: str
    old: str | None  # verdict in OLD (None: not in OLD)
    new: str | None  # verdict in NEW (None: not in NEW)
    message: str  # NEW's message (OLD's for a removed case)
    root_cause: str | None = None  # NEW's root cause id


@dataclass
class RunDiff:
    old_label: str
    new_label: str
    old_overall: str
    new_overall: str
    worse: list[Change] = field(default_factory=list)
    better: list[Change] = field(default_factory=list)
    changed: list[Change] = field(default_factory=list)
    added: list[Change] = field(default_factory=list)
    removed: list[Change] = field(default_factory=list)
    not_run: list[Change] = field(default_factory=list)
    #: "profile.first_index: 0 → 1", "version: 0.1.0 → 0.2.0"...: why verdicts may differ besides the box
    context: list[str] = field(default_factory=list)
    new_root_causes: list[str] = field(default_factory=list)  # "RC1 [F2] title (n cases)"
    gone_root_causes: list[str] = field(default_factory=list)
    unchanged: int = 0

    @property
    def got_worse(self) -> bool:
        return bool(self.worse)

    def counts(self) -> dict[str, int]:
        return {"worse": len(self.worse), "better": len(self.better), "changed": len(self.changed),
                "added": len(self.added), "removed": len(self.removed), "not_run": len(self.not_run),
                "unchanged": self.unchanged}

    def to_dict(self) -> dict[str, Any]:
        out = asdict(self)
        out["counts"] = self.counts()
        out["got_worse"] = self.got_worse
        return out


def _label(doc: dict[str, Any], path: str) -> str:
    suite = doc["suite"]
    parts = [p for p in (path, str(suite.get("started") or ""), str(suite.get("target") or "")) if p]
    return " · ".join(parts)


def _root_cause_lines(doc: dict[str, Any]) -> dict[tuple[str, ...], str]:
    out: dict[tuple[str, ...], str] = {}
    for r in doc.get("root_causes", []):
        if isinstance(r, dict):
            key = (str(r.get("kind", "")), *map(str, r.get("clauses", [])), str(r.get("title", "")))
            out[key] = f"{r.get('id', '?')} [{', '.join(map(str, r.get('clauses', [])))}] " \
                       f"{one_line(r.get('title', ''), 200)} ({len(r.get('cases', []))} cases)"
    return out


def _context(old: dict[str, Any], new: dict[str, Any]) -> list[str]:
    notes = []
    for key in ("version", "registry_version", "target", "udp_target", "extension", "role"):
        a, b = old["suite"].get(key), new["suite"].get(key)
        if a != b and (a or b):
            notes.append(f"{key}: {a if a not in (None, '') else '(none)'} → {b if b not in (None, '') else '(none)'}")
    po, pn = old["suite"].get("profile") or {}, new["suite"].get("profile") or {}
    for key in sorted(set(po) | set(pn)):
        if po.get(key) != pn.get(key):
            notes.append(f"profile.{key}: {po.get(key, '(unset)')} → {pn.get(key, '(unset)')}")
    return notes


def compare(old: dict[str, Any], new: dict[str, Any], old_path: str = "OLD", new_path: str = "NEW") -> RunDiff:
    """The comparison of two summary.json documents (as :func:`~.load.load_summary` returns them)."""
    old_cases = {c.id: c for c in cases_of(old)}
    new_cases = {c.id: c for c in cases_of(new)}
    diff = RunDiff(_label(old, old_path), _label(new, new_path),
                   overall_line(list(old_cases.values()), suite_of(old)),
                   overall_line(list(new_cases.values()), suite_of(new)), context=_context(old, new))
    not_run = set(new["suite"].get("not_run") or [])
    for cid, n in new_cases.items():
        o = old_cases.get(cid)
        change = Change(cid, n.clauses or (o.clauses if o else ()), n.title, o.verdict.value if o else None,
                        n.verdict.value, n.message, n.root_cause)
        if o is None:
            (diff.worse if n.verdict in BAD else diff.added).append(change)
        elif o.verdict is n.verdict:
            diff.unchanged += 1
        elif n.verdict in BAD and rank(n.verdict) < rank(o.verdict):
            diff.worse.append(change)
        elif o.verdict in BAD and rank(n.verdict) > rank(o.verdict):
            diff.better.append(change)
        else:
            diff.changed.append(change)
    for cid, o in old_cases.items():
        if cid not in new_cases:
            change = Change(cid, o.clauses, o.title, o.verdict.value, None, o.message)
            (diff.not_run if cid in not_run else diff.removed).append(change)
    old_rc, new_rc = _root_cause_lines(old), _root_cause_lines(new)
    diff.new_root_causes = [line for key, line in new_rc.items() if key not in old_rc]
    diff.gone_root_causes = [line for key, line in old_rc.items() if key not in new_rc]
    # worst first, then run order (dicts keep NEW's order)
    diff.worse.sort(key=lambda c: rank(Verdict(c.new)))
    return diff


# -- rendering ---------------------------------------------------------------------------------
SECTIONS = (
    ("worse", N_("Got worse")),
    ("better", N_("Got better")),
    ("changed", N_("Other verdict changes")),
    ("added", N_("Cases added")),
    ("removed", N_("Cases removed")),
    ("not_run", N_("Not run in NEW (it was cut short)")),
)


def _arrow(c: Change) -> str:
    return f"{c.old or _('(new case)')} → {c.new or _('(gone)')}"


def summary_line(diff: RunDiff) -> str:
    """``3 worse, 1 better, 2 other changes, 0 added, 0 removed, 270 unchanged``."""
    n = diff.counts()
    line = _("{worse} worse, {better} better, {changed} other changes, {added} added, {removed} removed, "
             "{unchanged} unchanged").format(**n)
    return line + (_(", {not_run} not run").format(**n) if n["not_run"] else "")


def render_text(diff: RunDiff) -> str:
    lines = [f"OLD: {diff.old_label}", f"NEW: {diff.new_label}",
             _("OLD result: {overall}").format(overall=diff.old_overall),
             _("NEW result: {overall}").format(overall=diff.new_overall)]
    if diff.context:
        lines.append(_("Runs differ in: ") + "; ".join(diff.context))
    for causes, title in ((diff.new_root_causes, _("New root causes")), (diff.gone_root_causes, _("Root causes gone"))):
        if causes:
            lines.append(f"{title} ({len(causes)}):")
            lines += [f"  {line}" for line in causes]
    for name, title in SECTIONS:
        changes: list[Change] = getattr(diff, name)
        if not changes:
            continue
        lines.append(f"{_(title)} ({len(changes)}):")
        width = max(len(_arrow(c)) for c in changes)
        for c in changes:
            rc = f" ({c.root_cause})" if c.root_cause else ""
            lines.append(f"  {_arrow(c):<{width}}  {c.id}  [{', '.join(c.clauses)}]{rc}  {one_line(c.message, 160)}")
    lines.append((_("WORSE: ") if diff.got_worse else _("not worse: ")) + summary_line(diff))
    return "\n".join(lines)


def _md(text: str, limit: int = 200) -> str:
    return one_line(text, limit).replace("|", "\\|").replace("<", "&lt;").replace(">", "&gt;")


def render_markdown(diff: RunDiff) -> str:
    verdict = "**Got worse**" if diff.got_worse else "No regression"
    lines = [f"### iSight conformance: {verdict}: {summary_line(diff)}", "",
             "| | Run | Result |", "|---|---|---|",
             f"| OLD | {_md(diff.old_label)} | {_md(diff.old_overall)} |",
             f"| NEW | {_md(diff.new_label)} | {_md(diff.new_overall)} |", ""]
    if diff.context:
        lines += ["Runs differ in: " + "; ".join(f"`{_md(c)}`" for c in diff.context), ""]
    for causes, title in ((diff.new_root_causes, "New root causes"), (diff.gone_root_causes, "Root causes gone")):
        if causes:
            lines += [f"#### {title} ({len(causes)})", ""] + [f"- {_md(line, 300)}" for line in causes] + [""]
    for name, title in SECTIONS:
        changes: list[Change] = getattr(diff, name)
        if not changes:
            continue
        lines += [f"#### {title} ({len(changes)})", "", "| Case | Clauses | Verdict | Message |", "|---|---|---|---|"]
        for c in changes[:MARKDOWN_ROWS]:
            rc = f" ({c.root_cause})" if c.root_cause else ""
            lines.append(f"| `{_md(c.id, 80)}` | {', '.join(c.clauses)} | {_arrow(c)}{rc} | {_md(c.message)} |")
        if len(changes) > MARKDOWN_ROWS:
            lines.append(f"| … | | | {len(changes) - MARKDOWN_ROWS} more (see `isight-conformance diff` as text or JSON) |")
        lines.append("")
    return "\n".join(lines).rstrip() + "\n"


def render(diff: RunDiff, fmt: str) -> str:
    """``fmt``: "text", "markdown" or "json"."""
    if fmt == "markdown":
        return render_markdown(diff)
    if fmt == "json":
        import json

        return json.dumps(diff.to_dict(), indent=2, ensure_ascii=False) + "\n"
    return render_text(diff) + "\n"

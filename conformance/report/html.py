"""report.html: the self-contained report an integrator reads, prints and signs.

One file, no external reference (inline CSS and SVG; a few lines of optional inline
script for filtering, the page works without it). Jinja2 with autoescape on; every
string also passes :func:`~.summary.clean_text` (through the environment's
``finalize``), so whatever a box sent shows as visible escapes, never as markup.

Content, in order, so the printed document reads as an acceptance document: what was
tested and the overall result (run facts; for an acceptance package the device under
test, the test system, the run ID, the manifest's hash and the declared / observed table,
:mod:`.html_acceptance`; the profile with non-default settings highlighted), the sign-off
block with the statement that the results apply only to the item tested, the root causes, the findings (FAIL, ERROR,
NON-STRICT and INCONCLUSIVE cases grouped by root cause, one line each), the changes
since a baseline run (``run --baseline``), the clause table, totals by verdict, then
every case in a ``<details>``. On paper a case prints as one line unless it is a print
card (:mod:`.html_cases`), whose evidence is cut to a bounded size; on screen all of it
stays one click away.
"""

from __future__ import annotations

import dataclasses
import functools
import os
import re
from collections.abc import Sequence
from datetime import datetime, timezone
from pathlib import Path
from typing import Any

import jinja2
from markupsafe import Markup

from .. import i18n
from ..i18n import N_, _
from ..model.verdicts import VERDICT_ORDER, CaseResult, Level, RootCause, SuiteInfo, Verdict, broken_verdict
from ..protocol import DEFAULT_PROFILE
from ..protocol.clauses import all_clauses
from ..protocol.clauses import families as registry_families
from ..runtime.profile_options import PROFILE_OPTIONS
from .clausetext import clause_text
from .diff import SECTIONS, RunDiff, summary_line
from .html_acceptance import acceptance_view, page_footer
from .html_cases import (
    CARD_VERDICTS,
    WIRE_HEAD,
    WIRE_PRINT_HEAD,
    WIRE_PRINT_TAIL,
    WIRE_TAIL,
    anchor_of,
    case_view,
    css_class,
    hexdump,
    pcap_href,
    print_cards,
)
from .html_diagnosis import diagnosis_view
from .summary import (
    CLAUSES,
    FAMILIES,
    atomic_write_bytes,
    by_clause,
    clean_text,
    format_duration,
    overall_line,
    overall_state,
    registry_version,
    totals,
)

__all__ = ["WIRE_HEAD", "WIRE_TAIL", "css_class", "hexdump", "pcap_href", "render_html", "write_html"]
NOT_RUN_SHOWN = 30  # ids of cases not run listed in the header of an incomplete run
CHIPS_PRINTED = 12  # case chips per clause on paper (those that did not pass)

#: What each verdict means, for the reader who signs.
VERDICT_MEANING: dict[Verdict, str] = {
    Verdict.FAIL: N_("a MUST requirement is broken: the box does not conform"),
    Verdict.ERROR: N_("the suite itself failed; the case says nothing about the box: rerun it"),
    Verdict.NON_STRICT: N_("a SHOULD requirement is broken: allowed, but worth raising with the vendor"),
    Verdict.INCONCLUSIVE: N_("could not be judged (box not ready, unreachable): neither pass nor fail"),
    Verdict.INFORMATIONAL: N_("behaviour recorded where PROTOCOL.md allows a choice (MAY): never failing"),
    Verdict.SKIP: N_("not applicable to this run (no UDP target, extension not implemented, deselected)"),
    Verdict.PASS: N_("the requirement is met"),
}

EXTENSION_MEANING = {
    "detected": N_("implemented (detected): E cases run"),
    "not implemented": N_("not implemented (detected): E cases SKIP"),
    "forced on": N_("forced on by the command line: E cases run"),
    "on": N_("forced on by the command line: E cases run"),
    "off": N_("switched off by the command line: E cases SKIP"),
    "auto": N_("auto-detection requested"),
}


def extension_meaning(how: str) -> str:
    """The report's extension line: what the session's detection saw, and what it means for the cases."""
    if how in EXTENSION_MEANING:
        return _(EXTENSION_MEANING[how])
    if how.startswith("implemented"):
        return _("{how}: E cases run").format(how=how)
    if how.startswith("not implemented"):
        return _("{how}: E cases SKIP, A5-02 judges 26/27 as unknown actions").format(how=how)
    return how


# -- small presentation helpers --------------------------------------------------------
def display_time(iso: str) -> str:
    """``2026-05-09T07:35:25.123+00:00`` -> ``2026-05-09 07:35:25 UTC``; other text as given."""
    try:
        when = datetime.fromisoformat(iso.replace("Z", "+00:00"))
    except (ValueError, AttributeError):
        return iso
    if when.tzinfo is None:
        return when.strftime("%Y-%m-%d %H:%M:%S")
    return when.astimezone(timezone.utc).strftime("%Y-%m-%d %H:%M:%S UTC")


def profile_rows(profile: dict[str, Any]) -> list[dict[str, Any]]:
    """One row per profile setting: flag, value, PROTOCOL.md default, changed?"""
    defaults = DEFAULT_PROFILE.to_dict()
    options = {o.field: o for o in PROFILE_OPTIONS}

    def shown(field: str, value: Any) -> str:
        value = getattr(value, "value", value)
        if field == "strict" and isinstance(value, bool):
            return "strict" if value else "lenient"
        return str(value)

    rows = []
    for name, value in profile.items():
        opt = options.get(name)
        known = name in defaults
        rows.append({
            "name": name,
            "flag": opt.flag if opt else "",
            "help": re.sub(r"^\[[^]]*\]\s*", "", _(opt.help)) if opt else "",
            "clause": (re.match(r"^\[([^]]*)\]", opt.help) or [None, ""])[1] if opt else "",
            "value": shown(name, value),
            "default": shown(name, defaults[name]) if known else _("(not a PROTOCOL.md setting)"),
            "changed": not known or getattr(value, "value", value) != defaults[name],
        })
    return rows


# -- rendering -------------------------------------------------------------------------
def _finalize(value: Any) -> Any:
    if value is None:
        return ""
    if isinstance(value, str) and not isinstance(value, Markup):
        return clean_text(value)
    return value


@functools.cache
def environment() -> jinja2.Environment:
    env = jinja2.Environment(
        loader=jinja2.PackageLoader("conformance.report", "templates"),
        autoescape=True, finalize=_finalize, trim_blocks=True, lstrip_blocks=True,
        undefined=jinja2.StrictUndefined, extensions=["jinja2.ext.i18n"],
    )
    i18n_environment(env)
    env.filters["vclass"] = css_class
    return env


def i18n_environment(env: jinja2.Environment) -> None:
    """Templates translate through the active language (``{% trans %}``, ``_()``; babel.cfg extracts them):
    ``vname`` shows a verdict with its word beside it, ``lname`` a requirement level."""
    env.policies["ext.i18n.trimmed"] = True
    env.install_gettext_callables(i18n.gettext, i18n.ngettext, newstyle=True)  # type: ignore[attr-defined]
    env.filters["vname"] = lambda v: i18n.beside(str(getattr(v, "value", v)))
    env.filters["lname"] = lambda lv: i18n.level_name(str(getattr(lv, "value", lv)))


def page_counter() -> Markup:
    """The printed page footer's CSS ``content`` value: "Page N of M" in the active language."""
    words = _("Page {page} of {pages}").replace('"', "'")
    css = '"' + words.replace("{page}", '" counter(page) "').replace("{pages}", '" counter(pages) "') + '"'
    return Markup(css.removeprefix('"" ').removesuffix(' ""'))


def clause_on_paper(case_ids: Sequence[str], verdict_of: dict[str, Verdict]) -> dict[str, Any]:
    """What a clause row's cases column prints: the chips of (at most CHIPS_PRINTED) FAIL,
    ERROR, NON-STRICT and INCONCLUSIVE cases, and the count of every case by verdict."""
    bad = [cid for cid in case_ids if verdict_of.get(cid) in CARD_VERDICTS]
    counts = totals(CaseResult(cid, "", (), Level.MUST, verdict_of[cid]) for cid in case_ids if cid in verdict_of)
    words = ", ".join(f"{n} {v}" for v, n in counts.items() if n)
    more = len(bad) - CHIPS_PRINTED
    return {"chips": set(bad[:CHIPS_PRINTED]),
            "note": i18n.ngettext("{n} case: {words}", "{n} cases: {words}", len(case_ids)).format(
                n=len(case_ids), words=words)
                    + (_(" ({more} more not passing are not named here)").format(more=more) if more > 0 else "")}


def root_cause_views(root_causes: Sequence[RootCause], cases: Sequence[CaseResult],
                     link: dict[str, tuple[str, str]]) -> list[dict[str, Any]]:
    """One view per root cause: its clauses with their text, evidence and the cases it
    explains (counted by verdict)."""
    by_id = {c.id: c for c in cases}
    views = []
    for rc in root_causes:
        explained = [by_id[cid] for cid in rc.cases if cid in by_id]
        counts = totals(explained)
        views.append({
            "id": rc.id, "anchor": "rc-" + re.sub(r"[^A-Za-z0-9_-]", "_", rc.id), "title": rc.title,
            "level": rc.level.value, "kind": rc.kind, "cls": css_class(broken_verdict(rc.level)),
            "clauses": [clause_text(c) for c in rc.clauses], "evidence": hexdump(rc.evidence, limit=256),
            "n_cases": len(rc.cases), "counts": [(v, n) for v, n in counts.items() if n],
            "first": link.get(rc.cases[0], ("", ""))[0] if rc.cases else "",
            "diagnosis": diagnosis_view(rc),
        })
    return views


def findings(cases: Sequence[CaseResult], root_causes: Sequence[RootCause]) -> list[dict[str, Any]]:
    """The FAIL, ERROR, NON-STRICT and INCONCLUSIVE cases in groups: one per root cause
    (in root-cause order), then those no root cause explains; worst first in each."""
    known = {rc.id for rc in root_causes}
    groups: dict[str | None, list[CaseResult]] = {rc.id: [] for rc in root_causes}
    groups[None] = []
    order = {v: i for i, v in enumerate(VERDICT_ORDER)}
    for case in cases:
        if case.verdict in CARD_VERDICTS:
            groups[case.root_cause if case.root_cause in known else None].append(case)
    titles = {rc.id: rc.title for rc in root_causes}
    return [{"root_cause": rid, "title": titles.get(rid or "", ""),
             "cases": sorted(members, key=lambda c: order[c.verdict])}
            for rid, members in groups.items() if members]


def diff_view(diff: RunDiff | None) -> dict[str, Any] | None:
    if diff is None:
        return None
    return {"diff": diff, "summary": summary_line(diff),
            "sections": [(title, getattr(diff, name)) for name, title in SECTIONS if getattr(diff, name)]}


def render_html(suite: SuiteInfo, cases: list[CaseResult], report_dir: str | os.PathLike[str] = ".",
                pcap_base: Path | None = None, root_causes: Sequence[RootCause] = (),
                diff: RunDiff | None = None, acceptance: dict[str, Any] | None = None) -> str:
    """The report as a string; pcap links are made relative to ``report_dir``."""
    report_dir = Path(report_dir)
    taken: set[str] = set()
    cards = print_cards(cases)
    views = [case_view(c, anchor_of(c.id, taken), suite, report_dir, pcap_base, i in cards)
             for i, c in enumerate(cases)]
    link: dict[str, tuple[str, str]] = {}  # case id -> (anchor, css class), for the clause table
    for v in views:
        link.setdefault(v["id"], (v["anchor"], v["cls"]))
    clause_results = by_clause(cases)
    families = []
    lang, registry = i18n.current(), all_clauses()
    for letter, name in registry_families(lang).items():
        rows = [dataclasses.replace(r, title=registry[r.clause].words(lang)[0]) if r.clause in registry else r
                for c, r in clause_results.items() if c[:1] == letter]
        families.append({"letter": letter, "name": name, "rows": rows})
    extra = [r for c, r in clause_results.items() if c[:1] not in FAMILIES]
    if extra:
        families.append({"letter": "?", "name": _("Other clause IDs named by cases"), "rows": extra})
    verdict_of = {c.id: c.verdict for c in cases}
    clause_print = {clause: clause_on_paper(row.cases, verdict_of) for clause, row in clause_results.items()}
    t = totals(cases)
    untested = [c for c in CLAUSES if not clause_results[c].cases]
    unjudged = [c for c in CLAUSES if clause_results[c].cases and not clause_results[c].tested]
    profile = profile_rows(dict(suite.profile))
    return environment().get_template("report.html.j2").render(
        suite=suite, started=display_time(suite.started), duration=format_duration(suite.duration_s),
        extension=extension_meaning(suite.extension),
        lang=i18n.current(), page_counter=page_counter(),
        profile=profile, changed=[r for r in profile if r["changed"]],
        overall=overall_line(cases, suite), overall_state=overall_state(cases, suite),
        totals=t, total=len(cases), order=[v.value for v in VERDICT_ORDER],
        meaning={v.value: _(m) for v, m in VERDICT_MEANING.items()},
        families=families, untested=untested, unjudged=unjudged, n_clauses=len(CLAUSES), link=link, clause_print=clause_print,
        levels=list(Level), cases=views, wire_head=WIRE_HEAD, wire_tail=WIRE_TAIL,
        wire_print=(WIRE_PRINT_HEAD, WIRE_PRINT_TAIL), n_cards=len(cards),
        root_causes=root_cause_views(root_causes, cases, link), findings=findings(cases, root_causes),
        not_run=suite.not_run[:NOT_RUN_SHOWN], n_not_run=len(suite.not_run),
        cases_total=max(suite.cases_total, len(cases)), baseline=diff_view(diff),
        registry_version=suite.registry_version or registry_version(),
        generated=datetime.now(timezone.utc).strftime("%Y-%m-%d %H:%M:%S UTC"),
        acceptance=acceptance_view(acceptance, report_dir, pcap_base),
        footer=page_footer(acceptance),
    )


def write_html(path: str | os.PathLike[str], suite: SuiteInfo, cases: list[CaseResult],
               pcap_base: Path | None = None, root_causes: Sequence[RootCause] = (),
               diff: RunDiff | None = None, acceptance: dict[str, Any] | None = None) -> None:
    """Write report.html atomically. Relative ``case.pcap`` paths are taken relative to
    ``pcap_base`` (default: the current directory); links are relative to the report."""
    path = Path(path)
    html = render_html(suite, cases, path.parent, pcap_base, root_causes, diff, acceptance)
    atomic_write_bytes(path, html.encode("utf-8", "replace"))

"""The words of the clauses a verdict cites, for the reports.

Every non-PASS verdict in the HTML report and on the terminal shows the text of the
clause(s) it judged, from the clause registry (:mod:`conformance.protocol.clauses`).
A clause ID the registry does not know (a case naming one by mistake) gets an empty
level and its ID as the title, so a report never fails for want of a text.

"The clause(s) it judged": the case's ``judged`` field when the suite set it; else the
clause IDs its ``requirement`` (or, failing that, its message) starts with, e.g.
``"A4/T1: the box does not answer..."``; with neither, every clause the case cites.
"""

from __future__ import annotations

import functools
import re
from dataclasses import dataclass

from ..i18n import _, current
from ..model.verdicts import CaseResult
from ..protocol.clauses import all_clauses

#: "A4/T1: ..." or "R1, B4 (MUST): ..." at the start of a requirement or message
_PREFIX = re.compile(r"^\s*((?:[A-Z]\d+)(?:\s*[/,]\s*[A-Z]\d+)*)\s*(?:\([A-Z]+\))?\s*:")
_ID = re.compile(r"[A-Z]\d+")


@dataclass(frozen=True)
class ClauseText:
    id: str
    level: str  # "MUST", "SHOULD", "MAY" or several ("MUST/SHOULD"); "" for an ID the registry does not know
    title: str
    text: str


def clause_text(clause_id: str) -> ClauseText:
    """The registry's level, title and text of a clause, in the active language."""
    return _clause_text(clause_id, current())


@functools.cache
def _clause_text(clause_id: str, lang: str) -> ClauseText:
    found = all_clauses().get(clause_id)
    if found is None:
        return ClauseText(clause_id, "", clause_id, _("{id} is not a clause of docs/PROTOCOL.md").format(id=clause_id))
    title, text = found.words(lang)
    return ClauseText(found.id, "/".join(found.levels), title, " ".join(text.split()))


def judged_clauses(case: CaseResult) -> tuple[str, ...]:
    """The clause IDs a verdict judged: ``case.judged``, the ID prefix of its requirement
    or message, else every clause the case cites (in the case's order, each once)."""
    if case.judged:
        return tuple(dict.fromkeys(case.judged))
    for source in (case.requirement, case.message):
        m = _PREFIX.match(source or "")
        if m:
            ids = tuple(dict.fromkeys(_ID.findall(m.group(1))))
            if ids:
                return ids
    return tuple(dict.fromkeys(case.clauses))


def judged_texts(case: CaseResult) -> list[ClauseText]:
    """:func:`clause_text` of each judged clause."""
    return [clause_text(c) for c in judged_clauses(case)]

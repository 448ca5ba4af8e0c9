"""No orphan FAIL: every FAIL the other sources leave unexplained gets a root cause (see :mod:`.rootcause`).

The sources of :mod:`.rootcause` name a defect once when it explains a group of verdicts; a FAIL
alone (a fuzz finding, a timing or UDP case, a malformation only one case sent) used to stand
without one, and a box with a MUST defect could end with no root cause at all. Here what is left:

* FAILs that share a groupable signature become one root cause from that signature (as a group
  would), even when only one case shows it;
* FAILs with a case's own finding, or with no signature, are grouped by the clause they judged:
  one root cause per clause, titled from the first case's message and naming how many cases it holds;
* FAILs of a case that could not reach the box become one root cause naming since when.

The diagnose phase puts each to the test like any other root cause; what no experiment confirms is
titled ``unconfirmed: …`` there, with its cases.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

from ..i18n import gettext
from ..model.signature import Sig, Signature
from ..model.verdicts import CaseResult, RootCause, Verdict
from .patterns import Claim, evidence_of

#: how a signature becomes a root cause (:func:`.rootcause._from_signature`)
FromSignature = Callable[[Signature, list[CaseResult]], RootCause]


def orphan_causes(rest: Sequence[CaseResult], from_signature: FromSignature) -> list[Claim]:
    """Root causes for the FAILs in ``rest`` (cases no other root cause explains)."""
    fails = [c for c in rest if c.verdict is Verdict.FAIL]
    by_sig: dict[Signature, list[CaseResult]] = {}
    by_clause: dict[str, list[CaseResult]] = {}
    unreachable: list[CaseResult] = []
    for case in fails:
        sig = case.signature
        if sig is not None and sig.kind is Sig.UNREACHABLE:
            unreachable.append(case)
        elif sig is not None and sig.groups:
            by_sig.setdefault(sig, []).append(case)
        else:
            by_clause.setdefault(_clause(case), []).append(case)
    out: list[Claim] = [(from_signature(sig, members), members) for sig, members in by_sig.items()]
    out += [(own_cause(clause, members), members) for clause, members in by_clause.items()]
    if unreachable:
        since = unreachable[0].signature.subject if unreachable[0].signature is not None else ""
        title = gettext("The box could not be reached by {n} case(s) (since {since})").format(
            n=len(unreachable), since=since)
        out.append((RootCause("", tuple(dict.fromkeys(_clause(c) for c in unreachable))[:3], title,
                              evidence_of(unreachable[0]), kind="unreachable"), unreachable))
    return out


def _clause(case: CaseResult) -> str:
    return next(iter(case.judged or case.clauses), "")


def own_cause(clause: str, members: list[CaseResult]) -> RootCause:
    """One root cause for FAILs of one clause that no signature groups: the first case's finding, and how many."""
    first = members[0]
    what = (first.message or first.observed or first.id).split(": expected")[0].strip()[:200]
    title = f"{first.id}: {what}"  # the case's own words, in the language of the run
    if len(members) > 1:
        title += gettext(" (and {n} more FAIL(s) of {clause})").format(n=len(members) - 1, clause=clause)
    kind = "fuzz" if first.signature is not None and first.signature.kind is Sig.FUZZ else "own"
    return RootCause("", (clause,) if clause else tuple(first.clauses[:1]), title, evidence_of(first), kind=kind)

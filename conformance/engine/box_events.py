"""Box-wide events: a stall of the whole box, reported once as its own root cause (T1, S4).

The fuzz campaign looks again at a probe left unanswered past time_out
(:mod:`conformance.fuzz.second_look`): when a fresh connection opened during the silence was
held too, the whole box stalled. The FUZZ case then carries ``details["box_stall"]`` (when it
began: after which bytes and how many writes; how long it lasted; who was affected), and
:func:`stall_causes` makes it a root cause, never an R6 or T1 verdict on the bytes in flight.
"""

from __future__ import annotations

from collections.abc import Sequence

from ..i18n import gettext
from ..model.signature import Sig
from ..model.verdicts import CaseResult, RootCause, Verdict
from .patterns import Claim

#: the root-cause kind (a finding of the session's own fresh connection: already an experiment)
BOX_STALL = "box-stall"


def _stalled(case: CaseResult) -> bool:
    sig = case.signature
    return bool(case.details.get("box_stall")) or (sig is not None and sig.kind is Sig.CASE and sig.subject == "box-stall")


def stall_causes(cases: Sequence[CaseResult]) -> list[Claim]:
    """A root cause per case that found the box stalled (the fuzz campaign's, with its numbers; a catalogue case's
    from the session's second fresh connection, :mod:`conformance.runtime.box_stall`)."""
    out: list[Claim] = []
    for case in cases:
        if case.verdict is not Verdict.FAIL or not _stalled(case):
            continue
        stalls = case.details.get("box_stall") or []
        if not stalls:
            title = gettext("{what}. T1/S4 ask for every connection answered within time_out — do not block the box's "
                            "loop").format(what=case.observed)
            out.append((RootCause("", ("T1", "S4"), title, f"{case.id}: {case.observed}"[:300], kind=BOX_STALL), [case]))
            continue
        first = stalls[0]
        text = (gettext("The whole box stalled for at least {s} s, once: it began after {case}'s write {writes} ({after}); "
                        "{affected}. T1/S4 ask for every connection answered within time_out — do not block the "
                        "box's loop") if first.get("at_least") else
                gettext("The whole box stalled for about {s} s, once: it began after {case}'s write {writes} ({after}); "
                        "{affected}. T1/S4 ask for every connection answered within time_out — do not block the "
                        "box's loop"))
        title = text.format(s=f"{float(first['lasted_s']):.1f}", case=case.id, writes=first["writes"],
                            after=first["after"], affected=first["affected"])
        more = f"; {len(stalls) - 1} more stall(s)" if len(stalls) > 1 else ""
        evidence = f"{case.id}: example {first['example']}, bytes {first['after']}{more}"
        out.append((RootCause("", ("T1", "S4"), title, evidence, kind=BOX_STALL), [case]))
    return out

"""Root causes: one defect that explains many verdicts, reported once and first.

A box with one systematic defect (every answer malformed the same way, CycleOn never
answered in time, one connection at a time, connections never freed, dead after some
input) fails or leaves unjudged many cases. :func:`find_root_causes` names each such
defect once, with the clause it breaks, the evidence and the cases it explains, the one
to fix first first (a broken MUST before a broken SHOULD, then the most explanatory), and
marks every explained case with its root cause's id.

Sources, in this order:

1. session facts (:mod:`.session`): the box never answered a NONE request (A4/T1);
   it serves one connection at a time (S4: explains the non-PASS cases that held two
   connections at once); it stopped accepting connections (S5) or died after a case's
   input (R2: explains that case and every later case left INCONCLUSIVE by it);
2. verdict *signatures* (what the defect looked like, set by the judging routine):
   every group of at least :data:`MIN_GROUP` non-PASS cases with the same signature.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

from ..i18n import gettext  # titles in the language of the run (the .format placeholders are named)
from .verdicts import CaseResult, Level, RootCause, Verdict

#: A signature shared by at least this many non-PASS cases is reported as a root cause.
MIN_GROUP = 2
_NOT_PASS = (Verdict.FAIL, Verdict.NON_STRICT, Verdict.ERROR, Verdict.INCONCLUSIVE)


@dataclass(frozen=True)
class SessionFacts:
    """What the session learnt about the box (see :class:`~.session.SessionState`)."""

    unresponsive: str = ""  # the baseline: what the box did with NONE, when it never answered it
    one_at_a_time: str = ""  # S4: the preflight's evidence, when the box served one connection at a time
    #: (case id, "dead" | "not-accepting", detail, connections opened, closed)
    deaths: tuple[tuple[str, str, str, int, int], ...] = ()


def find_root_causes(cases: Sequence[CaseResult], facts: SessionFacts = SessionFacts()) -> list[RootCause]:
    """The root causes, MUST before SHOULD, then most explanatory first; explained cases get ``root_cause`` set."""
    found: list[tuple[RootCause, list[CaseResult]]] = []
    taken: set[int] = set()

    def claim(cause: RootCause, members: list[CaseResult]) -> None:
        members = [c for c in members if id(c) not in taken]
        if members:
            taken.update(id(c) for c in members)
            found.append((cause, members))

    if facts.unresponsive:
        members = [c for c in cases if c.signature == "unreachable:session start"
                   or (c.id == "T1-00" and c.verdict is Verdict.FAIL)]
        claim(RootCause("", ("A4", "T1"), "The box answers no NONE request in this profile: nothing else could be "
                        "judged", facts.unresponsive, kind="unresponsive"), members)
    if facts.one_at_a_time:
        members = [c for c in cases if c.verdict in _NOT_PASS and c.signature != "unreachable:session start"
                   and (int(c.details.get("max_open_connections", 0)) >= 2 or "S4" in c.judged
                        or c.signature == "unreachable:connect")]  # its second connection was refused
        claim(RootCause("", ("S4",), gettext("The box serves one connection at a time: a second connection is not "
                                             "answered while the first is open"),
                        facts.one_at_a_time, kind="one-connection"), members)
    for case_id, kind, detail, opened, closed in facts.deaths:
        members = [c for c in cases if (c.id == case_id and c.verdict in _NOT_PASS)
                   or c.signature == f"unreachable:{case_id}"]
        if kind == "not-accepting":
            title = gettext("The box stops accepting connections after the suite has opened {opened} and closed "
                            "{closed}: closed connections are never freed").format(opened=opened, closed=closed)
            claim(RootCause("", ("S5", "R2"), title, detail, kind="connection-leak"), members)
        else:
            claim(RootCause("", ("R2",), gettext("The box stops answering new connections after the input of case "
                                                 "{case}").format(case=case_id),
                            detail, kind="dead-after-input"), members)
    groups: dict[str, list[CaseResult]] = {}
    for case in cases:
        if case.verdict in _NOT_PASS and case.signature and id(case) not in taken:
            groups.setdefault(_group_key(case.signature, cases), []).append(case)
    for signature, members in groups.items():
        if len(members) >= MIN_GROUP and not signature.startswith(("unreachable:", "case:")):
            claim(_from_signature(signature, members), members)
    # a broken MUST first, then the most cases; on a tie, a defect the catalogue's cases name before what
    # fuzzing found (a fuzz group names only the oracle's clause, e.g. T1 for a request left unanswered)
    found.sort(key=lambda item: (item[0].level is not Level.MUST, -len(item[1]), item[0].kind == "fuzz"))
    causes = []
    for n, (cause, members) in enumerate(found, 1):
        cause.id = f"RC{n}"
        cause.cases = [c.id for c in members]
        for case in members:
            case.root_cause = cause.id
        causes.append(cause)
    return causes


def _group_key(signature: str, cases: Sequence[CaseResult]) -> str:
    """A fuzz finding about malformed answers joins the group of the same malformation;
    parse errors left unanswered form one group whatever their action."""
    if signature.startswith("skipped:"):
        return "skipped:"
    if signature.startswith("fuzz:answer/"):
        clause = signature.split("/", 1)[1]
        peers = {c.signature for c in cases if c.signature.startswith(f"answer:{clause}:")}
        if len(peers) == 1:
            return peers.pop()
    return signature


def _from_signature(signature: str, members: list[CaseResult]) -> RootCause:
    first = members[0]
    kind, _, rest = signature.partition(":")
    evidence = _evidence(first)
    level = Level.MUST if any(c.verdict in (Verdict.FAIL, Verdict.ERROR) for c in members) else Level.SHOULD
    clauses = tuple(dict.fromkeys(c for m in members for c in (m.judged or m.clauses)))[:3]
    if kind == "answer":
        clause, _, detail = rest.partition(":")
        field, _, value = detail.partition("=")
        what = f"{field.replace('-', ' ')} {value}" if value else field.replace("-", " ")
        title = gettext("Every answer of the box is malformed the same way: {what} ({clause})").format(
            what=what, clause=clause)
        return RootCause("", (clause,), title, evidence, level=Level.MUST, kind="malformed-answers")
    if kind == "swapped":
        return RootCause("", ("F4", "A3"), gettext("The box writes error codes with their bytes swapped "
                                                   "(little-endian): 1001 goes out as 01 10"),
                         evidence, level=Level.MUST, kind="byte-order")
    if kind == "silence":  # a MUST: time_out (T1) is what it breaks; a SHOULD (R6: hangs after garbage) is not T1
        named = ("T1", *[c for c in clauses if c != "T1"][:1]) if level is Level.MUST else clauses
        return RootCause("", named,
                         gettext("The box does not answer {what} within time_out").format(what=rest), evidence,
                         level=level,
                         kind="unanswered")
    if kind == "skipped":
        return RootCause("", clauses, gettext("The box leaves requests that are parse errors unanswered (it goes on "
                                              "to the next request); A3 asks for the action's error code"),
                         evidence, level=level,
                         kind="unanswered-errors")
    if kind == "closed":
        return RootCause("", clauses, gettext("The box closes the connection instead of answering {what}").format(
            what=rest), evidence, level=level, kind="closes")
    if kind == "code":
        action, _, code = rest.partition(":")
        return RootCause("", clauses, gettext("The box answers {action} with error 0x{code} where the cases expect "
                                              "another code").format(action=action, code=code.upper()),
                         evidence, level=level, kind="wrong-code")
    if kind == "left-open":  # certify-robot: a connection the robot never closed (S5), so S1's last steps miss
        return RootCause("", ("S5", "S1"), gettext("The robot leaves its {what} connection open when its session "
                                                   "ends").format(what=rest.replace("+", " and ")),
                         evidence, level=Level.MUST, kind="left-open")
    if kind == "fuzz":
        return RootCause("", clauses, gettext("Fuzzing finds the same defect ({what})").format(what=rest), evidence,
                         level=level, kind="fuzz")
    return RootCause("", clauses, first.message.split(";")[0][:200], evidence, level=level, kind=kind)


def _evidence(case: CaseResult) -> str:
    parts = [f"{case.id}: {case.observed or case.message}"[:300]]
    if case.received_hex:
        parts.append(f"received {case.received_hex[:120]}")
    elif case.sent_hex:
        parts.append(f"sent {case.sent_hex[:120]}")
    return "; ".join(parts)

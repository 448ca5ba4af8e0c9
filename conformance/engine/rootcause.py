"""Root causes: one defect that explains many verdicts, reported once and first.

A box with one systematic defect (every answer malformed the same way, CycleOn never
answered in time, one connection at a time, connections never freed, dead after some
input) fails or leaves unjudged many cases. :func:`find_root_causes` names each such
defect once, with the clause it breaks, the evidence and the cases it explains, the one
to fix first first (a broken MUST before a broken SHOULD, then the most explanatory), and
marks every explained case with its root cause's id.

Sources, in this order:

1. session facts (:mod:`.run_state`): the box never answered a NONE request (A4/T1);
   it serves one connection at a time (S4: explains the non-PASS cases that held two
   connections at once); it stopped accepting connections (S5) or died after a case's
   input (R2: explains that case and every later case left INCONCLUSIVE by it);
2. what every answer shows (:mod:`.patterns`): the action never echoed (A2), one error
   code whatever the action (A3/A4);
3. acceptance that changes at a block position (:mod:`.patterns`, B3): the position named;
4. verdict *signatures* (what the defect looked like, set by the judging routine):
   every group of at least :data:`MIN_GROUP` non-PASS cases with the same signature;
5. every FAIL still unexplained (:mod:`.orphans`): no FAIL stands without a root cause.

A root cause's level is that of what it explains: MUST when it explains a FAIL, else SHOULD.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import Any

from ..i18n import gettext  # titles in the language of the run (the .format placeholders are named)
from ..model.signature import Death, DeathKind, Sig, Signature
from ..model.verdicts import CaseResult, Level, RootCause, Verdict
from .box_events import stall_causes
from .history_causes import history_causes
from .orphans import orphan_causes
from .patterns import Claim, block_position_cause, evidence_of, field_causes
from .transport_causes import transport_causes

#: A signature shared by at least this many non-PASS cases is reported as a root cause.
MIN_GROUP = 2
_NOT_PASS = (Verdict.FAIL, Verdict.NON_STRICT, Verdict.ERROR, Verdict.INCONCLUSIVE)
_SESSION_START = Signature.unreachable("session start")
_AT_CONNECT = Signature.unreachable("connect")
#: root causes read across every answer come before those of a case or a group of cases, at the same level
_FIELD_KINDS = ("unresponsive", "action-not-echoed", "constant-error", "malformed-answers", "byte-order")


@dataclass(frozen=True)
class SessionFacts:
    """What the session learnt about the box (see :class:`~.session.SessionState`)."""

    unresponsive: str = ""  # the baseline: what the box did with NONE, when it never answered it
    one_at_a_time: str = ""  # S4: the preflight's evidence, when the box served one connection at a time
    deaths: tuple[Death, ...] = ()  # the box stopped answering after these cases (not the baseline's)
    first_index: int = 0  # the profile's first block index (B3)

    def to_dict(self) -> dict[str, Any]:
        return {"unresponsive": self.unresponsive, "one_at_a_time": self.one_at_a_time,
                "deaths": [d.to_dict() for d in self.deaths], "first_index": self.first_index}

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> SessionFacts:
        return cls(data["unresponsive"], data["one_at_a_time"], tuple(Death.from_dict(d) for d in data["deaths"]),
                   int(data.get("first_index", 0)))

    def merged(self, known: SessionFacts | None) -> SessionFacts:
        """These facts with what another worker's session of the same box learnt."""
        if known is None:
            return self
        return replace(self, unresponsive=self.unresponsive or known.unresponsive,
                       one_at_a_time=self.one_at_a_time or known.one_at_a_time, deaths=self.deaths + known.deaths)


def find_root_causes(cases: Sequence[CaseResult], facts: SessionFacts = SessionFacts()) -> list[RootCause]:
    """The root causes, MUST before SHOULD, then most explanatory first; explained cases get ``root_cause`` set."""
    found: list[Claim] = []
    taken: set[int] = set()

    def claim(cause: RootCause, members: list[CaseResult]) -> None:
        members = [c for c in members if id(c) not in taken]
        if members:
            taken.update(id(c) for c in members)
            found.append((cause, members))

    for cause, members in _session_causes(cases, facts):
        claim(cause, members)
    for cause, members in stall_causes(cases) + transport_causes([c for c in cases if id(c) not in taken]):  # T1/S4; F6, F7, R7
        claim(cause, members)
    for cause, members in history_causes([c for c in cases if id(c) not in taken]):  # E3 before the first cycle
        claim(cause, members)
    for cause, members in field_causes([c for c in cases if id(c) not in taken]):
        claim(cause, members)
    position = block_position_cause([c for c in cases if id(c) not in taken], facts.first_index)
    if position is not None:
        claim(*position)
    groups: dict[Signature, list[CaseResult]] = {}
    for case in cases:
        if case.verdict in _NOT_PASS and case.signature is not None and id(case) not in taken:
            groups.setdefault(_group_key(case.signature, cases, case), []).append(case)
    for signature, members in groups.items():
        if len(members) >= MIN_GROUP and signature.groups:
            claim(_from_signature(signature, members), members)
    for cause, members in orphan_causes([c for c in cases if id(c) not in taken], _from_signature):
        claim(cause, members)  # no FAIL without a root cause (issue 34)
    found = [(_levelled(cause, members), members) for cause, members in found]
    # a broken MUST first; at a level, what every answer shows, then the most cases; on a tie, a defect the
    # catalogue's cases name before what fuzzing found (a fuzz group names only the oracle's clause)
    found.sort(key=lambda item: (item[0].level is not Level.MUST, item[0].kind not in _FIELD_KINDS,
                                 -len(item[1]), item[0].kind == "fuzz"))
    causes = []
    for n, (cause, members) in enumerate(found, 1):
        cause.id = f"RC{n}"
        cause.cases = [c.id for c in members]
        for case in members:
            case.root_cause = cause.id
        causes.append(cause)
    return causes


def _levelled(cause: RootCause, members: list[CaseResult]) -> RootCause:
    """A root cause's level is that of what it explains: MUST when it explains a FAIL, else SHOULD."""
    cause.level = Level.MUST if any(c.verdict is Verdict.FAIL for c in members) else Level.SHOULD
    return cause


def _session_causes(cases: Sequence[CaseResult], facts: SessionFacts) -> list[Claim]:
    """What the session learnt: never answered NONE (A4/T1), one connection at a time (S4), deaths (R2, S5)."""
    out: list[Claim] = []
    if facts.unresponsive:
        members = [c for c in cases if c.signature == _SESSION_START or (c.id == "T1-00" and c.verdict is Verdict.FAIL)]
        out.append((RootCause("", ("A4", "T1"), "The box answers no NONE request in this profile: nothing else could "
                              "be judged", facts.unresponsive, kind="unresponsive"), members))
    if facts.one_at_a_time:
        members = [c for c in cases if c.verdict in _NOT_PASS and c.signature != _SESSION_START
                   and (int(c.details.get("max_open_connections", 0)) >= 2 or "S4" in c.judged
                        or c.signature == _AT_CONNECT)]  # its second connection was refused
        out.append((RootCause("", ("S4",), gettext("The box serves one connection at a time: a second connection is not "
                                             "answered while the first is open"), facts.one_at_a_time, kind="one-connection"), members))
    for death in facts.deaths:
        since = Signature.unreachable(death.case_id)
        members = [c for c in cases if (c.id == death.case_id and c.verdict in _NOT_PASS) or c.signature == since]
        if death.kind is DeathKind.CONNECTION_LEAK:
            title = gettext("The box stops accepting connections after the suite has opened {opened} and closed "
                            "{closed}: closed connections are never freed").format(opened=death.opened,
                                                                                   closed=death.closed)
            out.append((RootCause("", ("S5", "R2"), title, death.detail, kind=death.kind.value), members))
        else:
            out.append((RootCause("", ("R2",), gettext("The box stops answering new connections after the input of case "
                                                  "{case}").format(case=death.case_id), death.detail, kind=death.kind.value), members))
    return out


#: one group for the silences after bad bytes (R6, SHOULD), whichever probe went unanswered
HANGS_AFTER_BAD_BYTES = Signature(Sig.SILENCE, "after-bad-bytes")


def _group_key(signature: Signature, cases: Sequence[CaseResult], case: CaseResult | None = None) -> Signature:
    """A fuzz finding about malformed answers joins the group of the same malformation;
    parse errors left unanswered form one group whatever their action; so do the requests left
    unanswered behind bad bytes (an R6 SHOULD, not a late answer: the probe's action is the case's choice)."""
    if signature.kind is Sig.SKIPPED:
        return Signature(Sig.SKIPPED)
    if case is not None and case.verdict is not Verdict.FAIL and (
            (signature.kind is Sig.SILENCE and "R6" in case.judged)
            or (signature.kind is Sig.FUZZ and signature.clause == "R6")):  # fuzzing found the same hang
        return HANGS_AFTER_BAD_BYTES
    if signature.kind is Sig.FUZZ and signature.field == "answer":
        peers = {s for s in (c.signature for c in cases) if s is not None and s.kind is Sig.ANSWER
                 and s.clause == signature.clause}
        if len(peers) == 1:
            return peers.pop()
    return signature


def _from_signature(sig: Signature, members: list[CaseResult]) -> RootCause:
    first = members[0]
    evidence = evidence_of(first)
    level = Level.MUST if any(c.verdict in (Verdict.FAIL, Verdict.ERROR) for c in members) else Level.SHOULD
    clauses = tuple(dict.fromkeys(c for m in members for c in (m.judged or m.clauses)))[:3]
    kind, rest = sig.kind, sig.subject
    if kind is Sig.ANSWER:
        what = f"{sig.field.replace('-', ' ')} {sig.value}" if sig.value else sig.field.replace("-", " ")
        title = gettext("Every answer of the box is malformed the same way: {what} ({clause})").format(
            what=what, clause=sig.clause)
        return RootCause("", (sig.clause,), title, evidence, kind="malformed-answers")
    if kind is Sig.SWAPPED:
        return RootCause("", ("F4", "A3"), gettext("The box writes error codes with their bytes swapped "
                                                   "(little-endian): 1001 goes out as 01 10"), evidence, kind="byte-order")
    if sig == HANGS_AFTER_BAD_BYTES:
        return RootCause("", ("R6",), gettext("After bytes that are not a request the box goes silent: the requests "
                                              "behind them are not answered within time_out (R6: it SHOULD "
                                              "resynchronise)"), evidence, kind="unanswered")
    if kind is Sig.SILENCE:  # a MUST: time_out (T1) is what it breaks; a SHOULD (R6: hangs after garbage) is not T1
        named = ("T1", *[c for c in clauses if c != "T1"][:1]) if level is Level.MUST else clauses
        return RootCause("", named, gettext("The box does not answer {what} within time_out").format(what=rest), evidence, kind="unanswered")
    if kind is Sig.SKIPPED:
        return RootCause("", clauses, gettext("The box leaves requests that are parse errors unanswered (it goes on "
                                              "to the next request); A3 asks for the action's error code"), evidence, kind="unanswered-errors")
    if kind is Sig.CLOSED:
        return RootCause("", clauses, gettext("The box closes the connection instead of answering {what}").format(what=rest), evidence,
                         kind="closes")
    if kind is Sig.CODE:
        return RootCause("", clauses, gettext("The box answers {action} with error 0x{code} where the cases expect "
                                              "another code").format(action=rest, code=sig.value.upper()), evidence, kind="wrong-code")
    if kind is Sig.LEFT_OPEN:  # certify-robot: a connection the robot never closed (S5), so S1's last steps miss
        return RootCause("", ("S5", "S1"), gettext("The robot leaves its {what} connection open when its session "
                                                   "ends").format(what=rest.replace("+", " and ")), evidence, kind="left-open")
    if kind is Sig.FUZZ:
        return RootCause("", clauses, gettext("Fuzzing finds the same defect ({what})").format(what=str(sig).partition(":")[2]), evidence,
                         kind="fuzz")
    return RootCause("", clauses, first.message.split(";")[0][:200], evidence, kind=kind.value)

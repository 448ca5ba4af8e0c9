"""The diagnose phase: after the catalogue, before the reports; at most :data:`BUDGET_S` seconds.

:func:`diagnose` runs the experiment families (:mod:`.families`, :mod:`.reproduce`) against the
box on fresh connections, then gives each root cause the mechanism that explains it
(:mod:`.match`): its title becomes the mechanism's (threshold, clause, fix direction), its
``diagnosis`` lists the hypotheses considered and the experiment (with its bytes) that ruled each
in or out, and ``confirmed`` says whether one was confirmed. A root cause no experiment confirms
is titled "unconfirmed: …" and comes after every confirmed one; two root causes one mechanism
explains become one. Root causes the session's own live checks found (a box that never answers,
one connection at a time, a death, connections never freed) were already proven on fresh
connections and are kept as they are.

Bounded: every wait is cut to what is left of the deadline, no exchange starts after it, and a box
that stopped answering fresh connections is not probed at all.
"""

from __future__ import annotations

import sys
import time
import traceback
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..engine.rootcause import SessionFacts
from ..harness.target import Target
from ..model.verdicts import CaseResult, Level, RootCause
from ..protocol import Action, Profile
from ..runtime.run_state import SessionState
from . import (
    answer_family,
    batching,
    block_length,
    conn_deaths,
    conn_limit,
    conn_peers,
    conn_state,
    death_inputs,
    deaths,
    families,
    match,
    prog_idx_value,
    result_state,
    segments,
    timing,
    timing_judge,
    titles,
    udp_family,
)
from .dimensions import refine_cycle, refine_refused
from .experiments import BLOCK_ACTIONS, Prober
from .families import CORE, CYCLES, NONE, POSE, Found
from .hypotheses import Expect, Experiment, Hypothesis, Mechanism, Status
from .isolate import Isolator
from .repro import repro_entry

#: the phase's bound in seconds (on top of the catalogue; inside the 120 s per box)
BUDGET_S = 20.0


@dataclass
class Diagnosed:
    causes: list[RootCause]
    repros: dict[str, tuple[tuple[bytes, Expect], ...]] = field(default_factory=dict)  # root cause id -> repro
    elapsed_s: float = 0.0
    exchanges: int = 0


class _Lab:
    """The families run so far: their experiments, mechanisms and stories."""

    def __init__(self) -> None:
        self.experiments: dict[str, Experiment] = {}
        self.mechanisms: list[Mechanism] = []
        self.stories: dict[str, tuple[Status, str, str]] = {}
        self.undecided: list[str] = []  # stories a family could not tell apart (see Found.undecided)

    def add(self, found: Found) -> Found:
        self.experiments[found.experiment.name] = found.experiment
        self.mechanisms += found.mechanisms
        if found.undecided:
            self.undecided.append(found.undecided)
        for kind, (status, why) in found.stories.items():
            self.stories[kind] = (status, why, found.experiment.name)
        return found


def diagnose(causes: Sequence[RootCause], cases: Sequence[CaseResult], facts: SessionFacts, target: Target | None,
             profile: Profile, time_out_s: float, budget_s: float = BUDGET_S,
             udp_target: Target | None = None) -> Diagnosed:
    """The root causes diagnosed (re-titled, re-ordered, merged), with their repros."""
    start = time.monotonic()
    causes = list(causes)
    if not causes:
        return Diagnosed(causes)
    lab = _Lab()
    facts_by = {c.id: match.facts_of(c, cases) for c in causes}
    own: dict[str, Found] = {}
    probed = [c for c in causes if c.kind not in match.SESSION_KINDS + udp_family.KINDS + result_state.KINDS]
    prober = None if target is None else Prober(target, profile, time_out_s, start + budget_s)
    dead = {c.id: deaths.check(prober, c, cases) for c in causes if c.kind in deaths.DEATH_KINDS and prober is not None}
    still_dead = any(v.confirmed for v in dead.values()) or (prober is None and bool(facts.unresponsive or facts.deaths))
    transport = [c for c in causes if c.kind in udp_family.KINDS]  # F6, F7, R7: their own family
    if prober is not None and transport and not still_dead:
        lab_udp = udp_family.run(prober, udp_target, transport)
        for cause in transport:
            udp_family.assign(cause, lab_udp)
    for cause in (c for c in causes if c.kind == batching.KIND):
        if prober is not None:
            batching.run(prober, cause, time_out_s)  # no NONE within time_out: silent, late, or answers held back?
    for cause in (c for c in causes if c.kind in result_state.KINDS):
        if prober is not None and not still_dead:
            result_state.run(prober, cause, cases)  # E3: wrong before the first cycle only?
    if prober is not None and probed and not still_dead:
        _run(prober, lab, probed, facts_by, cases, own)
    out = _assign(causes, facts_by, lab, own, dead)
    death_inputs.name(out.causes, cases)  # a death named with the input it followed (issue 34)
    conn_deaths.name(out.causes, cases, facts.deaths)  # ... or with a count of connections, as the evidence says
    elapsed = round(time.monotonic() - start, 3)
    for cause in out.causes:
        if cause.diagnosis is not None:
            cause.diagnosis["phase_s"] = elapsed
    out.elapsed_s, out.exchanges = elapsed, prober.count if prober is not None else 0
    return out


def _run(p: Prober, lab: _Lab, probed: list[RootCause], facts_by: dict[str, match.CauseFacts],
         cases: Sequence[CaseResult], own: dict[str, Found]) -> None:
    involved = set().union(*(facts_by[c.id].asked for c in probed))
    p.exchange([p.valid_request(int(Action.CYCLE_OFF))], settle=False)  # the catalogue may have left a cycle on (S3: idle first)
    alone = lab.add(families.answers(p, [*CORE, *(a for a in CYCLES if a in involved)])).alone
    refine_refused(p, lab.mechanisms)  # a valid request refused: its block length read little-endian? (issue 34)
    if p.unreachable:
        return
    lab.add(answer_family.shapes(p, lab.experiments.get("alone"), involved))  # answers built wrongly, field by field
    lab.add(prog_idx_value.run(p, involved))  # the ProgIdx int32 echoed another way: which reading?
    extra = any(m.kind == "extra-answer" for m in lab.mechanisms)  # two answers, or one answer and a stray byte?
    if extra and lab.add(answer_family.trailing(p, involved)).mechanisms:
        lab.mechanisms = [m for m in lab.mechanisms if m.kind != "extra-answer"]  # the stray byte read as one
    lab.add(answer_family.byte_order(p, lab.experiments.get("alone"), probed, cases))
    lab.add(block_length.run(p, probed, cases))  # a wrong block length accepted: the accepted range
    waiting = [c for c in probed if match.pick(lab.mechanisms, facts_by[c.id]) is None]
    for found in timing.run(p, waiting, {c.id: facts_by[c.id].asked for c in waiting}, alone):
        lab.add(found)  # not answered within time_out: late, a stall, latency per block? (first: they wait long)
    usable = [a for a, v in alone.items() if a in BLOCK_ACTIONS and v.kind in ("ok", "extra", "echo")]
    lab.add(families.size(p, usable))
    lab.add(families.after_error(p, [NONE, POSE, *sorted(a for a in involved if a in CORE and a not in (NONE, POSE))],
                                 alone))

    def unexplained() -> list[RootCause]:
        return [c for c in probed if match.pick(lab.mechanisms, facts_by[c.id]) is None and c.id not in own]

    isolator = Isolator(p)  # the failure-inducing difference isolated; else the case sent again (issue 34)
    by_id = {c.id: c for c in cases}
    for cause in unexplained():  # segmentation first: a close in a split stream is not an idle close (R3/R4)
        if segments.involved([by_id[i] for i in cause.cases if i in by_id]) and p.left() > 1.0:
            mine = isolator.diagnose(cause, cases)
            if mine.mechanisms:
                own[cause.id] = mine
    for found in timing.counts(p, unexplained(), {c.id: facts_by[c.id].asked for c in probed}):
        lab.add(found)  # requests counted on one connection: a count to the first silence, latency by the request
    _closes(p, lab, [c for c in unexplained() if c.kind == "closes" or facts_by[c.id].closed], cases)  # conn_state
    if unexplained() or any(m.kind in ("refuses-valid", "missing-answer") and POSE in m.actions for m in lab.mechanisms):
        lab.add(families.cycle(p, alone))  # a pose refused alone may be accepted in a cycle (S3)
        refine_cycle(p, lab.mechanisms)  # ... on the connection holding the cycle only? (issue 34)
    if unexplained():
        lab.add(families.per_connection(p))
    for cause in unexplained():
        if p.left() > 1.0:
            own[cause.id] = isolator.diagnose(cause, cases)


def _closes(p: Prober, lab: _Lab, closing: list[RootCause], cases: Sequence[CaseResult]) -> None:
    """A close the requests alone did not show: another connection's doing, a limit on
    connections open at once, idle time, or connection age."""
    alone = lab.experiments.get("alone")
    if closing and not conn_state.closed_at_once(alone) and not p.unreachable:
        if conn_peers.decided(lab.add(conn_peers.run(p))):  # another connection's doing (S4)
            return
        if conn_limit.decided(lab.add(conn_limit.run(p))):  # a limit on connections held open (R5)
            return
        members = [c for c in cases if c.id in set(closing[0].cases)]
        lab.add(conn_state.run(p, alone, conn_state.closed_instead_of(members)))


def _session_diagnosis(cause: RootCause) -> dict[str, Any]:
    h = Hypothesis(cause.kind, cause.title, Status.CONFIRMED, "session",
                   "found by the session's own checks: NONE requests on fresh connections")
    return {"confirmed": True, "mechanism": cause.kind, "catalogue_title": cause.title, "hypotheses": [h.to_dict()],
            "experiments": [{"name": "session", "question": "a NONE request on a fresh connection, before and after "
                             "the cases (the session's liveness checks)", "finding": cause.evidence, "exchanges": [],
                             "exchange_count": 0}]}


def _assign(causes: list[RootCause], facts_by: dict[str, match.CauseFacts], lab: _Lab,
            own: dict[str, Found], dead: dict[str, deaths.Verdict] | None = None) -> Diagnosed:
    kept: list[RootCause] = []
    repros: dict[str, tuple[tuple[bytes, Expect], ...]] = {}
    owner: dict[int, RootCause] = {}  # id(mechanism) -> the root cause it already explains
    owner_of: dict[str, RootCause] = {}  # an undecided story -> the root cause it already titles
    for cause in causes:
        if dead and cause.id in dead:  # a death the phase put to the test again
            verdict = dead[cause.id]
            cause.diagnosis = deaths.diagnosis(cause, verdict)
            cause.confirmed = verdict.confirmed
            if not verdict.confirmed:
                cause.title = titles.unconfirmed(f"{cause.title} ({verdict.why})")
            kept.append(cause)
            continue
        if cause.kind in udp_family.KINDS + result_state.KINDS:  # diagnosed by their family (or left as read)
            kept.append(cause)
            continue
        if cause.kind in match.SESSION_KINDS:
            cause.confirmed, cause.diagnosis = True, cause.diagnosis or _session_diagnosis(cause)
            kept.append(cause)
            continue
        f = facts_by[cause.id]
        mine = own.get(cause.id)
        stories = dict(lab.stories)
        experiments = dict(lab.experiments)
        if mine is not None:
            stories.update({k: (s, why, mine.experiment.name) for k, (s, why) in mine.stories.items()})
            experiments[mine.experiment.name] = mine.experiment
        chosen = match.pick(lab.mechanisms, f) or (mine.mechanisms[0] if mine is not None and mine.mechanisms else None)
        if chosen is not None and id(chosen) in owner:
            first = owner[id(chosen)]
            first.cases += [c for c in cause.cases if c not in first.cases]
            continue
        hyps = match.hypotheses(f, cause.title, chosen, stories)
        original = cause.title
        if chosen is None:
            undecided = lab.undecided[0] if lab.undecided and POSE in f.asked else ""
            if undecided and undecided in owner_of:  # one story for both: one root cause
                owner_of[undecided].cases += [c for c in cause.cases if c not in owner_of[undecided].cases]
                continue
            if undecided:
                owner_of[undecided] = cause
            cause.confirmed, cause.title = False, titles.unconfirmed(undecided or original)
        else:
            owner[id(chosen)] = cause
            cause.confirmed, cause.title = True, chosen.title
            if chosen.kind not in match.SAME_STORY.get(cause.kind, set()) and chosen.kind not in ("reproduces",
                                                                                                   "order-dependent"):
                cause.kind = chosen.kind
                cause.clauses = chosen.clauses
            repros[cause.id] = chosen.repro
        used = {h.experiment for h in hyps if h.experiment}
        cause.diagnosis = {
            "confirmed": cause.confirmed, "mechanism": chosen.kind if chosen is not None else None,
            "catalogue_title": original, "detail": chosen.to_dict() if chosen is not None else {},
            "hypotheses": [h.to_dict() for h in hyps],
            "experiments": [e.to_dict() for name, e in experiments.items() if name in used],
        }
        kept.append(cause)
    return _ordered(kept, repros)


def _rank(cause: RootCause) -> tuple[bool, bool, bool, bool]:
    """Confirmed first; then a broken MUST first; then a mechanism named (or the session's finding) before a story
    only seen again on a fresh connection; within them a mechanism in the answers before an answer late past the
    run's time_out (:data:`.timing_judge.TIME_ONLY`: it depends on the time_out given; the catalogue's order within)."""
    mechanism = (cause.diagnosis or {}).get("mechanism")
    return (cause.confirmed is False, cause.level is not Level.MUST, mechanism in ("reproduces", "order-dependent"),
            mechanism in timing_judge.TIME_ONLY)


def _ordered(causes: list[RootCause], repros: dict[str, tuple[tuple[bytes, Expect], ...]]) -> Diagnosed:
    """Confirmed root causes first (see :func:`_rank`), numbered again; cases re-pointed by :func:`relink`."""
    ordered = sorted(causes, key=_rank)
    renamed: dict[str, tuple[tuple[bytes, Expect], ...]] = {}
    for n, cause in enumerate(ordered, 1):
        new = f"RC{n}"
        if cause.id in repros:
            renamed[new] = repros[cause.id]
            if cause.diagnosis is not None:
                one_write = bool(cause.diagnosis.get("detail", {}).get("one_write"))
                cause.diagnosis["repro"] = repro_entry(new, repros[cause.id], one_write)
        cause.id = new
    return Diagnosed(ordered, renamed)


def relink(causes: Sequence[RootCause], cases: Sequence[CaseResult]) -> None:
    """Every case a root cause explains carries that root cause's (new) id."""
    owner = {case_id: cause.id for cause in causes for case_id in cause.cases}
    for case in cases:
        if case.root_cause is not None or case.id in owner:
            case.root_cause = owner.get(case.id)


def run_phase(state: SessionState, cases: Sequence[CaseResult], causes: Sequence[RootCause],
              facts: SessionFacts) -> list[RootCause]:
    """The phase for one box's session (the hook of the run): its root causes diagnosed, cases re-pointed.
    The bundled reference box (no ``--target``) is not diagnosed."""
    target = state.settings.target
    if target is None or not causes:
        return list(causes)
    try:
        done = diagnose(causes, cases, facts, target, state.profile, state.time_out_s, udp_target=state.udp_target())
    except Exception as exc:  # a defect of the phase never costs the run its reports: the causes stay as read
        frames = traceback.extract_tb(exc.__traceback__)
        where = next((f for f in reversed(frames) if "conformance" in f.filename), frames[-1])
        note = f"the diagnose phase stopped ({type(exc).__name__}: {exc}, at {Path(where.filename).name}:{where.lineno})"
        print(f"isight-conformance: {note}; the root causes are reported as read from the verdicts", file=sys.stderr)
        for cause in causes:
            cause.diagnosis = {"confirmed": None, "error": note}
        return list(causes)
    relink(done.causes, cases)
    return done.causes

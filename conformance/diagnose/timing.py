"""Time and thresholds, the live half: answer latency against the action, the block count and the request's
index on its connection, each measured on fresh connections with every wait bounded (the judgements and titles
are in :mod:`.timing_judge`).

:func:`run` puts a root cause "not answered within time_out" to three experiments, cheapest first:

* :func:`late` — the action the box left unanswered, sent alone and waited for past time_out (at most
  :data:`LATE_FACTOR` × time_out, cut to the phase's deadline), with a NONE on another connection meanwhile:
  a late answer to that action, a stall of the whole box, or a silence;
* :func:`per_block` — a block action at a few block counts, each on a fresh connection: latency's slope over
  the block count and the count where it crosses time_out;
* :func:`budget` — requests one at a time on one connection to the first unanswered, then a fresh connection
  (answered again: a per-connection count) and the same count again on another (the same number: a budget).
"""

from __future__ import annotations

import math
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

from ..harness.client import Answer, Closed, Malformed, Outcome, TcpConnection
from ..harness.target import Unreachable
from ..model.verdicts import RootCause
from ..protocol import Action
from . import timing_judge as J
from .experiments import BLOCK_ACTIONS, Prober, block_request, heard
from .families import Found
from .hypotheses import LEGAL_CODES, Alone, Exchange, Expect, Experiment, Mechanism, Reading, Status
from .titles import name

#: the wait for a late answer, in time_outs (bounded by the phase's deadline too)
LATE_FACTOR = 2.0
#: actions waited for past time_out, at most (an action answered at once costs one answer)
LATE_ACTIONS = 3
#: an answer within this is "at once": the other connection's NONE is sent after it
AT_ONCE_S = 0.2
#: block counts measured first (a third is chosen from their slope)
FIRST_COUNTS = (1, 8)
#: the count measured when the first two show too little growth to read a slope from
WIDE_COUNT = 64
#: requests counted on one connection to the first unanswered, at most
BUDGET_MAX = 1000
#: one count's share of what is left of the phase, and its bound in seconds (a box slow to answer is not counted to
#: the end: the phase's other experiments need their time)
COUNT_SHARE, COUNT_S = 0.25, 3.0
#: the wait that calls one request of the count unanswered: this many times the slowest answer so far, within
BUDGET_QUIET = (0.5, 20.0)
#: the root-cause kinds these experiments are for
FOR_KINDS = ("unanswered",)
NONE, POSE = int(Action.NONE), int(Action.POSE)
#: the actions a per-connection count or slowdown touches: every request
ALL_ACTIONS = {NONE, *BLOCK_ACTIONS, int(Action.CYCLE_ON), int(Action.CYCLE_OFF)}


def _expect(action: int) -> Expect:
    return Expect("valid", action, LEGAL_CODES.get(action, (0,)))


def _reading(outcome: Outcome | None) -> Reading:
    if isinstance(outcome, (Answer, Malformed)):
        return Reading((heard(outcome),))
    return Reading((), isinstance(outcome, Closed))


def _dial(p: Prober, note: str) -> TcpConnection | None:
    p.count += 1
    try:
        return p.dialer.dial(note)
    except Unreachable as exc:
        p.unreachable = str(exc)
        return None


def _timed(conn: TcpConnection, frame: bytes, wait_s: float) -> tuple[Outcome | None, float]:
    """``frame`` sent; what came within ``wait_s`` (None: nothing) and its latency."""
    sent = time.monotonic()
    if not conn.send(frame, "diagnose: timed"):
        return Closed(False, 0.0), 0.0
    got = conn.next_outcome(max(0.0, wait_s), since=sent)
    return (got if isinstance(got, (Answer, Malformed, Closed)) else None), time.monotonic() - sent


# -- late vs stall vs silence ----------------------------------------------------------------------------------------
def late(p: Prober, action: int) -> Found:
    t = p.dialer.time_out_s
    found = Found(Experiment(f"late {action:02X}", f"{name(action)} alone, waited for up to {LATE_FACTOR:g} × time_out, and a NONE "
                                     f"on another connection sent {AT_ONCE_S:g} s after it"))
    wait = min(LATE_FACTOR * t, p.left() - 0.2)
    if wait <= t * 1.05:
        found.stories[J.LATE] = (Status.UNTESTED, "not enough of the phase left to wait past time_out")
        return found
    frame, none = p.valid_request(action), p.valid_request(NONE)
    a = _dial(p, "diagnose: late")
    if a is None:
        found.stories[J.LATE] = (Status.UNTESTED, "no connection")
        return found
    try:
        start = time.monotonic()
        if not a.send(frame, "diagnose: the request waited for"):
            found.stories[J.LATE] = (Status.UNTESTED, "closed before the request went out")
            return found
        first = a.next_outcome(AT_ONCE_S, since=start)
        other, other_latency, other_after = None, None, 0.0
        if not isinstance(first, (Answer, Malformed, Closed)):
            b = _dial(p, "diagnose: meanwhile")
            if b is not None:
                other_after = time.monotonic() - start
                try:
                    other, _ = _timed(b, none, start + wait - time.monotonic())
                    other_latency = other.latency_s if isinstance(other, (Answer, Malformed)) else None
                finally:
                    b.close("diagnose")
                found.experiment.exchanges.append(Exchange((none,), (_reading(other),)))
            first = a.next_outcome(max(0.0, start + wait - time.monotonic()), since=start)
        latency = first.latency_s if isinstance(first, (Answer, Malformed)) else None
    finally:
        a.close("diagnose")
    found.experiment.exchanges.insert(0, Exchange((frame,), (_reading(first),)))
    if action == int(Action.CYCLE_ON) and latency is not None:  # the cycle left on is ended (S3: idle first)
        p.exchange([p.valid_request(int(Action.CYCLE_OFF))], settle=False)
    facts = J.LateFacts(action, t, wait, latency, other_latency, other_after)
    kind, detail, stories = J.late_story(facts)
    for k, status, why in stories:
        found.stories[k] = (status, why)
    found.experiment.finding = "; ".join(why for _, _, why in stories[:1])
    if kind:
        found.mechanisms.append(_mech(kind, {action}, found, ("T1", "S4") if kind == J.STALL else ("T1",),
                                      [(frame, _expect(action))], J.title_of(kind, detail), detail))
    return found


def _mech(kind: str, actions: set[int], found: Found, clauses: tuple[str, ...],
          repro: Sequence[tuple[bytes, Expect]], title: str, detail: Mapping[str, Any]) -> Mechanism:
    return Mechanism(kind, frozenset(actions), found.experiment.name, title, clauses, tuple(repro), dict(detail))


# -- latency against the block count ---------------------------------------------------------------------------------
def _latency(p: Prober, found: Found, frame: bytes) -> float | None:
    """``frame`` alone on a fresh connection: its answer's latency (None: none within time_out)."""
    conn = _dial(p, "diagnose: latency")
    if conn is None:
        return None
    try:
        got, _ = _timed(conn, frame, p.dialer.wait_s())
    finally:
        conn.close("diagnose")
    found.experiment.exchanges.append(Exchange((frame,), (_reading(got),)))
    return got.latency_s if isinstance(got, Answer) and got.frame.error_code == 0 else None


def third_count(points: Sequence[tuple[int, float]], time_out_s: float) -> int | None:
    """The third block count to measure: where the line of the first two reaches half of time_out (within 255,
    and not one measured already); None when the first two show no growth."""
    (n0, t0), (n1, t1) = points[0], points[-1]
    k = (t1 - t0) / (n1 - n0)
    if t1 - t0 < J.GROWTH_MIN_S or k <= 0:
        return None
    n = min(255, n0 + math.floor((0.5 * time_out_s - t0) / k))
    if n <= n1:
        n = (n0 + n1) // 2
    return n if n not in (n0, n1) else None


def per_block(p: Prober, action: int) -> Found:
    t = p.dialer.time_out_s
    found = Found(Experiment("latency-per-block", f"{name(action)} at a few block counts, each alone on a fresh "
                                                  "connection: latency against the block count"))
    points: list[tuple[int, float]] = []
    for n in FIRST_COUNTS:
        lat = _latency(p, found, block_request(p, action, n))
        if lat is None:
            break
        points.append((n, lat))
    if len(points) == 2 and points[1][1] - points[0][1] < J.GROWTH_MIN_S:  # too little at 8 blocks to see: at more
        lat = _latency(p, found, block_request(p, action, WIDE_COUNT))
        if lat is not None:
            points.append((WIDE_COUNT, lat))
    n3 = third_count(points, t) if len(points) == 2 else None
    if n3 is not None and p.left() > 0.5 * t + 1.0:
        lat = _latency(p, found, block_request(p, action, n3))
        if lat is not None:
            points.append((n3, lat))
    slope = J.slope_of(points, t)
    measured = ", ".join(f"{n}: {J.seconds(s)}" for n, s in sorted(points))
    if slope is None:
        why = f"no growth with the block count on one line ({measured})"
        found.stories[J.PER_BLOCK] = (Status.RULED_OUT if len(points) >= 2 else Status.UNTESTED, why)
        found.experiment.finding = why
        return found
    why = f"{J.seconds(slope.per_block_s)} more per block ({measured}), each on a fresh connection"
    found.stories[J.PER_BLOCK] = (Status.CONFIRMED, why)
    found.experiment.finding = why
    crossing = slope.crossing or 255
    detail = {"action": action, "per_block_s": round(slope.per_block_s, 4), "crossing": slope.crossing,
              "points": [[n, round(s, 3)] for n, s in sorted(points)], "time_out_s": t}
    found.mechanisms.append(_mech(J.PER_BLOCK, {action}, found, ("T1",),
                                  [(block_request(p, action, crossing), _expect(action))],
                                  J.per_block_title(action, slope, points, t), detail))
    return found


# -- a count of requests on one connection ----------------------------------------------------------------------------
@dataclass
class Count:
    """Requests one at a time on one connection: the latency of each answered one, and whether one went unanswered
    (``silent``: the count before it) or the phase ran out first."""

    latencies: list[float] = field(default_factory=list)
    silent: bool = False
    out_of_time: bool = False

    @property
    def answered(self) -> int:
        return len(self.latencies)


def _count(p: Prober, found: Found, frame: bytes, most: int) -> Count:
    """Requests one at a time on one fresh connection until one goes unanswered (or ``most`` are answered, or the
    latency grows with the request's index: :func:`.timing_judge.index_growth`)."""
    out = Count()
    conn = _dial(p, "diagnose: count")
    if conn is None:
        out.out_of_time = True
        return out
    slowest, until = 0.0, time.monotonic() + min(COUNT_S, COUNT_SHARE * p.left())
    try:
        for i in range(most):
            if p.left() < 0.5 or time.monotonic() > until:
                out.out_of_time = True
                return out
            quiet = min(p.dialer.wait_s(), max(BUDGET_QUIET[0], BUDGET_QUIET[1] * slowest))
            got, _ = _timed(conn, frame, quiet)
            if not isinstance(got, (Answer, Malformed)):
                found.experiment.exchanges.append(Exchange((frame,) * (i + 1), (Reading(),) * i + (_reading(got),)))
                out.silent = True
                return out
            slowest = max(slowest, got.latency_s)
            out.latencies.append(got.latency_s)
            if i % 10 == 9 and J.index_growth(out.latencies) is not None:
                return out
    finally:
        conn.close("diagnose")
    return out


def budget(p: Prober, action: int = NONE) -> Found:
    found = Found(Experiment(f"request-budget {action:02X}", f"{name(action)} requests one at a time on one "
                             f"connection (at most {BUDGET_MAX}) to the first unanswered, with each one's latency; "
                             "then a fresh connection, and the same count again on another"))
    none = p.valid_request(action)
    first = _count(p, found, none, BUDGET_MAX)
    growth = J.index_growth(first.latencies)
    if growth is not None:
        return _per_request(p, found, none, growth, first, action)
    n = first.answered
    if not first.silent or n < 2:
        why = (f"{n} requests on one connection all answered" + (" (then out of time)" if first.out_of_time else "")
               if not first.silent else f"unanswered from request {n + 1}: a missing answer, not a count")
        found.stories[J.BUDGET] = (Status.RULED_OUT if not first.out_of_time else Status.UNTESTED, why)
        found.experiment.finding = why
        return found
    fresh = p.exchange([none], settle=False)
    fresh_ok = fresh is not None and fresh.reached and not _expect(action).broken_by(fresh.reading(0))
    if fresh is not None:
        found.experiment.exchanges.append(fresh)
    again = _count(p, found, none, n + 1) if fresh_ok else None
    replay = None if again is None or again.out_of_time else again.answered
    kind, detail, stories = J.budget_story(J.BudgetFacts(BUDGET_MAX, n, fresh_ok, replay))
    for k, status, why in stories:
        found.stories[k] = (status, why)
    found.experiment.finding = stories[0][2]
    if kind:
        found.mechanisms.append(_mech(kind, ALL_ACTIONS, found, ("A1", "S6"), [(none, _expect(action))] * (n + 1),
                                      J.title_of(kind, detail), detail))
    return found


def _per_request(p: Prober, found: Found, none: bytes, growth: J.Growth, first: Count, action: int) -> Found:
    """Latency grew with the request's index: a fresh connection's NONE tells per connection from box-wide."""
    conn = _dial(p, "diagnose: fresh after growth")
    fresh_s = None
    if conn is not None:
        try:
            got, _ = _timed(conn, none, p.dialer.wait_s())
            fresh_s = got.latency_s if isinstance(got, Answer) else None
        finally:
            conn.close("diagnose")
    kind, stories = J.per_request_story(growth, fresh_s, first.answered)
    for k, status, why in stories:
        found.stories[k] = (status, why)
    found.experiment.finding = stories[0][2]
    if kind and fresh_s is not None:
        detail = {"knee": growth.knee, "per_request_s": round(growth.per_request_s, 5), "base_s": round(growth.base_s, 4),
                  "last": growth.last, "last_s": round(growth.last_s, 3), "fresh_s": round(fresh_s, 4)}
        found.mechanisms.append(_mech(kind, ALL_ACTIONS, found, ("T2", "T1"), [(none, _expect(action))] * growth.last,
                                      J.per_request_title(growth, fresh_s), detail))
    return found


# -- the family ---------------------------------------------------------------------------------------------------------
def _actions(causes: Sequence[RootCause], asked: Mapping[str, frozenset[int]]) -> list[int]:
    """The requests the causes asked for that PROTOCOL.md defines (a fuzz case's bytes may carry any action byte:
    an unknown one has no valid request to time)."""
    known = {int(a) for a in Action}
    return sorted(set().union(*(asked.get(c.id, frozenset()) for c in causes if c.kind in FOR_KINDS)) & known)


def run(p: Prober, causes: Sequence[RootCause], asked: Mapping[str, frozenset[int]],
        alone: Mapping[int, Alone]) -> list[Found]:
    """Late vs stall vs silence, then latency per block, for the root causes of :data:`FOR_KINDS` (``asked``: each
    one's actions; ``alone``: how each action was answered alone), until one confirms a mechanism."""
    out: list[Found] = []
    actions = _actions(causes, asked)
    waited = sorted((a for a in actions if a != NONE), key=lambda a: a in BLOCK_ACTIONS)[:LATE_ACTIONS]
    for action in waited:  # late, or a stall? (alone's NONE may have been read with a late answer: each is waited for)
        out.append(late(p, action))
        if out[-1].mechanisms:
            return out
    for action in actions:  # answered alone: late with more blocks?
        v = alone.get(action)
        if action in BLOCK_ACTIONS and (v is None or v.kind == "ok"):
            out.append(per_block(p, action))
            if out[-1].mechanisms:
                return out
    return out


def counts(p: Prober, causes: Sequence[RootCause], asked: Mapping[str, frozenset[int]]) -> list[Found]:
    """The requests of one connection counted (:func:`budget`) for the root causes of :data:`FOR_KINDS` still
    unexplained (after the cheaper families: a box slow to answer makes a count slow): NONE requests, then poses
    when the root cause asked for poses and every NONE was answered (a box may count only its stream's poses)."""
    if not any(c.kind in FOR_KINDS for c in causes) or p.left() <= 1.0:
        return []
    out = [budget(p)]
    status = out[0].stories.get(J.BUDGET, (Status.UNTESTED, ""))[0]
    if not out[0].mechanisms and status is Status.RULED_OUT and POSE in _actions(causes, asked) and p.left() > 1.0:
        out.append(budget(p, POSE))
    return out

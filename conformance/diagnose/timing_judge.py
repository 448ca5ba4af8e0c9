"""Time and thresholds, the pure half: what the timing experiments measured, what they tell apart, the titles.

Three stories about a request "not answered within time_out" that the answers alone cannot tell apart:

* **late** vs **stall** vs **silence**: the request sent alone, the wait carried past time_out (bounded), and a
  NONE on another connection sent meanwhile. Answered late while the other connection is answered at once: the
  box answers that action late (:data:`LATE`); the other connection kept waiting too: the whole box stalls
  (:data:`STALL`); no answer even past time_out: a silence, not a late answer.
* **latency per block**: the same action at a few block counts, each on a fresh connection (so neither the
  request's index on its connection nor the order explains it), the slope of latency over block count and the
  count where it crosses time_out (:data:`PER_BLOCK`).
* **request budget**: requests on one connection counted to the first silence, then a fresh connection: answered
  again, a per-connection count (:data:`BUDGET`); not answered, a box-wide one.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from ..i18n import gettext
from ..i18n.ordinals import ordinal
from .hypotheses import Status
from .titles import name

LATE = "late-answer"
STALL = "stall"
SILENT = "missing-answer"  # never answered, even past time_out, while the box serves another connection
PER_BLOCK = "latency-per-block"
BUDGET = "connection-count"  # the same story as families.per_connection, told with its count to the first silence
PER_REQUEST = "latency-per-request"
#: the mechanism kinds this module confirms (in the order one explains a root cause before the next)
KINDS = (PER_BLOCK, PER_REQUEST, BUDGET, STALL, LATE)
#: findings that hold only against the run's time_out (a late answer, latency per block): a root cause they explain
#: is ranked after the root causes explained by a mechanism in the answers themselves
TIME_ONLY = (LATE, PER_BLOCK)
#: a latency this much over the one-block latency, and a slope at least this steep, is a growth with the block count
GROWTH_MIN_S = 0.15
SLOPE_MIN_S = 0.002
#: the third point of a slope must lie this close (relative) to the line through the first two
LINEAR_TOLERANCE = 0.35
Story = tuple[str, Status, str]


def seconds(s: float) -> str:
    """A duration as a title writes it: "62 ms", "5.5 s"."""
    if s < 0.0005:
        return "< 1 ms"
    return f"{s * 1000:.0f} ms" if s < 1.0 else f"{s:.1f} s"


# -- late vs stall vs silence ------------------------------------------------------------------------------------
@dataclass(frozen=True)
class LateFacts:
    """One request alone, waited for past time_out; a NONE on another connection sent ``other_after_s`` later."""

    action: int
    time_out_s: float
    waited_s: float  # how long the wait for the request's answer lasted
    latency_s: float | None  # when its answer came (None: none within the wait)
    other_latency_s: float | None  # the NONE's latency on the other connection (None: unanswered within its wait)
    other_after_s: float = 0.0


def late_story(f: LateFacts) -> tuple[str, dict[str, Any], list[Story]]:
    """The confirmed kind (``""`` for none), its numbers, and each story's status."""
    if f.latency_s is None:
        why = f"no answer within {seconds(f.waited_s)} ({f.waited_s / f.time_out_s:.1f} × time_out)"
        if f.other_latency_s is not None and f.other_latency_s < f.time_out_s:  # the box served the other connection
            why += f"; a NONE on another connection meanwhile was answered in {seconds(f.other_latency_s)}"
            silent = {"action": f.action, "waited_s": round(f.waited_s, 3), "other_s": round(f.other_latency_s, 3)}
            return SILENT, silent, [(SILENT, Status.CONFIRMED, why), (LATE, Status.RULED_OUT, why),
                               (STALL, Status.RULED_OUT, why)]
        return "", {}, [(LATE, Status.RULED_OUT, why), (STALL, Status.RULED_OUT, why)]
    if f.latency_s <= f.time_out_s:
        why = f"answered in {seconds(f.latency_s)}, within time_out, when sent alone"
        return "", {}, [(LATE, Status.RULED_OUT, why), (STALL, Status.RULED_OUT, why)]
    d = {"action": f.action, "latency_s": round(f.latency_s, 3), "time_out_s": f.time_out_s,
         "other_s": None if f.other_latency_s is None else round(f.other_latency_s, 3)}
    late_why = f"answered after {seconds(f.latency_s)}, past time_out ({seconds(f.time_out_s)})"
    other_done = None if f.other_latency_s is None else f.other_after_s + f.other_latency_s
    quick = other_done is not None and f.other_latency_s is not None and f.other_latency_s < min(
        f.time_out_s, 0.5 * (f.latency_s - f.other_after_s))
    if quick:
        why = f"{late_why}; a NONE on another connection meanwhile was answered in {seconds(f.other_latency_s or 0)}"
        return LATE, d, [(LATE, Status.CONFIRMED, why), (STALL, Status.RULED_OUT, why)]
    if other_done is None or other_done >= 0.8 * f.latency_s:
        what = "not answered" if f.other_latency_s is None else f"answered only after {seconds(f.other_latency_s)}"
        why = f"{late_why}; a NONE on another connection meanwhile was {what}"
        return STALL, d, [(STALL, Status.CONFIRMED, why), (LATE, Status.RULED_OUT, why)]
    why = f"{late_why}; the other connection's NONE came neither at once nor with it"
    return "", d, [(LATE, Status.CONSISTENT, why), (STALL, Status.CONSISTENT, why)]


def late_title(action: int, latency_s: float, time_out_s: float, other_s: float | None) -> str:
    return gettext("Answers {action} only after {late}, past time_out ({time_out}), while other requests are answered "
                   "at once (NONE on another connection meanwhile: {other}): T1 asks for every answer within "
                   "time_out — answer {action} at once (with an error code if it cannot be served yet)").format(
        action=name(action), late=seconds(latency_s), time_out=seconds(time_out_s), other=seconds(other_s or 0.0))


def stall_title(action: int, latency_s: float, time_out_s: float) -> str:
    return gettext("Stalls the whole box for {late} on {action}: no other connection is answered meanwhile, past "
                   "time_out ({time_out}): T1/S4 ask for every connection answered within time_out — do not block "
                   "the box while {action} is served").format(action=name(action), late=seconds(latency_s),
                                                              time_out=seconds(time_out_s))


# -- latency against block count ----------------------------------------------------------------------------------
@dataclass(frozen=True)
class Slope:
    per_block_s: float
    intercept_s: float
    crossing: int | None  # the smallest block count answered after time_out (None: not within 255)


def slope_of(points: Sequence[tuple[int, float]], time_out_s: float) -> Slope | None:
    """A latency that grows linearly with the block count, from (count, latency) points measured on fresh
    connections: None when it does not grow (by :data:`GROWTH_MIN_S` and :data:`SLOPE_MIN_S` a block) or the
    points are not on one line (the third within :data:`LINEAR_TOLERANCE` of the line of the first two)."""
    pts = sorted(points)
    if len(pts) < 3 or pts[-1][0] == pts[0][0]:
        return None
    (n0, t0), (n1, t1) = pts[0], pts[-1]
    k = (t1 - t0) / (n1 - n0)
    if t1 - t0 < GROWTH_MIN_S or k < SLOPE_MIN_S:
        return None
    for n, t in pts[1:-1]:
        predicted = t0 + k * (n - n0)
        if abs(t - predicted) > LINEAR_TOLERANCE * max(predicted - t0, GROWTH_MIN_S):
            return None
    b = t0 - k * n0
    crossing = math.floor((time_out_s - b) / k) + 1
    return Slope(k, b, crossing if 1 <= crossing <= 255 else None)


def per_block_title(action: int, slope: Slope, points: Sequence[tuple[int, float]], time_out_s: float) -> str:
    ordered = sorted(points)
    measured = gettext("at {counts} blocks: {times}").format(counts=" / ".join(str(n) for n, _ in ordered),
                                                             times=" / ".join(seconds(t) for _, t in ordered))
    if slope.crossing is None:
        return gettext("Answer latency grows with the block count: about {k} per block for {action} ({measured}): "
                       "T1 asks for every answer within time_out — do not spend time per block").format(
            k=seconds(slope.per_block_s), action=name(action), measured=measured)
    return gettext("Answer latency grows with the block count: about {k} per block for {action} ({measured}), so a "
                   "request of {n} or more blocks is answered after time_out ({time_out}): T1 asks for every answer "
                   "within time_out — do not spend time per block").format(
        k=seconds(slope.per_block_s), action=name(action), measured=measured, n=slope.crossing,
        time_out=seconds(time_out_s))


# -- a count of requests, per connection or box-wide ----------------------------------------------------------------
@dataclass(frozen=True)
class BudgetFacts:
    """Requests counted on one connection to the first unanswered (``answered``: how many were answered before it;
    None: all ``sent`` answered), a fresh connection tried after it, and the count again on a fresh connection."""

    sent: int
    answered: int | None
    fresh_answered: bool
    replay_answered: int | None = None  # the same count on another fresh connection: answered before the silence


def budget_story(f: BudgetFacts) -> tuple[str, dict[str, Any], list[Story]]:
    if f.answered is None:
        why = f"{f.sent} requests on one connection all answered"
        return "", {}, [(BUDGET, Status.RULED_OUT, why)]
    if not f.fresh_answered:
        why = (f"after {f.answered} answered requests a fresh connection was not answered either: a box-wide count or "
               f"a death, not a per-connection one")
        return "", {"n": f.answered}, [(BUDGET, Status.RULED_OUT, why)]
    if f.replay_answered is not None and f.replay_answered != f.answered:
        why = f"silent after {f.answered} answered requests, then after {f.replay_answered} on a fresh connection"
        return "", {"n": f.answered}, [(BUDGET, Status.CONSISTENT, why)]
    again = "" if f.replay_answered is None else f", and again after {f.replay_answered} on another fresh connection"
    why = f"request {f.answered + 1} on one connection went unanswered{again}; a fresh connection was answered"
    return BUDGET, {"n": f.answered}, [(BUDGET, Status.CONFIRMED, why)]


def budget_title(n: int) -> str:
    return gettext("Stops answering a connection after its {nth} request (request {m} and later go unanswered; a "
                   "fresh connection is answered again: a per-connection request budget?): A1 asks for every "
                   "request answered — do not limit the requests of a connection").format(nth=ordinal(n), m=n + 1)


# -- latency against the request's index on its connection ----------------------------------------------------------
#: the first requests of a connection whose median latency is the base
BASE_REQUESTS = 20
#: the last requests that must all be this much slower than the base, and grow by this much a request at least
TAIL_REQUESTS = 30
TAIL_OVER_S = 0.03
TAIL_SLOPE_S = 0.0003


@dataclass(frozen=True)
class Growth:
    base_s: float
    per_request_s: float
    knee: int  # the request (1-based) after which latency grows
    last: int  # the last request measured
    last_s: float


def _median(xs: Sequence[float]) -> float:
    ys = sorted(xs)
    return ys[len(ys) // 2]


def index_growth(latencies: Sequence[float]) -> Growth | None:
    """Latency that grows with the request's index on one connection (requests one at a time): the last
    :data:`TAIL_REQUESTS` all :data:`TAIL_OVER_S` over the base and rising by :data:`TAIL_SLOPE_S` a request at
    least (least squares); the knee where that line meets the base. None otherwise."""
    if len(latencies) < BASE_REQUESTS + TAIL_REQUESTS:
        return None
    base = _median(latencies[:BASE_REQUESTS])
    tail = list(latencies[-TAIL_REQUESTS:])
    if min(tail) < base + TAIL_OVER_S:
        return None
    xs = range(TAIL_REQUESTS)
    mx, my = (TAIL_REQUESTS - 1) / 2, sum(tail) / TAIL_REQUESTS
    k = sum((x - mx) * (y - my) for x, y in zip(xs, tail)) / sum((x - mx) ** 2 for x in xs)
    if k < TAIL_SLOPE_S:
        return None
    centre = len(latencies) - TAIL_REQUESTS + 1 + mx  # 1-based request index of the tail's centre
    knee = max(0, round(centre - (my - base) / k))
    return Growth(base, k, knee, len(latencies), tail[-1])


def per_request_story(g: Growth | None, fresh_s: float | None, sent: int) -> tuple[str, list[Story]]:
    """Growth on one connection, and a NONE's latency on a fresh connection after it: per connection when the
    fresh one is answered near the base, else the box slows for everyone (time since start, load)."""
    if g is None:
        return "", [(PER_REQUEST, Status.RULED_OUT, f"latency flat over {sent} requests on one connection")]
    seen = (f"from request {g.knee} on, about {seconds(g.per_request_s)} more per request "
            f"({seconds(g.base_s)} at first, {seconds(g.last_s)} at request {g.last})")
    if fresh_s is not None and fresh_s < g.base_s + 0.5 * (g.last_s - g.base_s):
        why = f"{seen}; a fresh connection answered in {seconds(fresh_s)}"
        return PER_REQUEST, [(PER_REQUEST, Status.CONFIRMED, why)]
    why = f"{seen}; a fresh connection was {'not answered' if fresh_s is None else 'slow too'}: not per connection"
    return "", [(PER_REQUEST, Status.CONSISTENT, why)]


def per_request_title(g: Growth, fresh_s: float) -> str:
    return gettext("Answer latency grows with each request on a connection: about {k} more per request after the "
                   "{nth} ({base} at first, {last} at request {n}; a fresh connection is answered in {fresh}), so a "
                   "steady stream builds a backlog: T1/T2 ask for every answer within time_out at the stream's rate "
                   "— do not let a connection's history slow its answers").format(
        k=seconds(g.per_request_s), nth=ordinal(g.knee) if g.knee else ordinal(1), base=seconds(g.base_s),
        last=seconds(g.last_s), n=g.last, fresh=seconds(fresh_s))


def silent_title(action: int, waited_s: float, other_s: float) -> str:
    return gettext("Never answers {action}: no answer within {waited} (past time_out) while a NONE on another "
                   "connection meanwhile was answered in {other}: A1/T1 ask for one answer within time_out — answer "
                   "every {action} (with an error code if it cannot be served)").format(
        action=name(action), waited=seconds(waited_s), other=seconds(other_s))


def title_of(kind: str, d: dict[str, Any], points: Sequence[tuple[int, float]] = ()) -> str:
    if kind == SILENT:
        return silent_title(int(d["action"]), float(d["waited_s"]), float(d["other_s"]))
    if kind == LATE:
        return late_title(int(d["action"]), float(d["latency_s"]), float(d["time_out_s"]), d.get("other_s"))
    if kind == STALL:
        return stall_title(int(d["action"]), float(d["latency_s"]), float(d["time_out_s"]))
    if kind == BUDGET:
        return budget_title(int(d["n"]))
    raise ValueError(kind)

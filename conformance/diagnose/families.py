"""The experiment families: live questions whose answers tell competing stories apart.

* :func:`answers` — each valid request alone on a fresh connection, a NONE right after it: echo wrong
  for one action vs for every action vs answers shifted by an extra (or a missing) answer; a valid
  request refused;
* :func:`size` — count limit vs byte-size limit vs index judged wrongly: 255 blocks at two block sizes,
  the threshold pinned by bisection at each, then wrong indexes at the position where acceptance changes;
* :func:`after_error` — state that leaks from an error answer into the next: a parse error, then a valid
  request (vs the same request alone, from :func:`answers`);
* :func:`cycle` — a request inside a cycle vs alone; :func:`per_connection` — many requests on one
  connection vs one.

Each returns its :class:`~.hypotheses.Experiment` and the :class:`~.hypotheses.Mechanism` it confirmed.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

from ..i18n import gettext
from ..protocol import Action
from . import titles
from .bisect import smallest_refused
from .experiments import BLOCK_ACTIONS, Prober, block_request
from .hypotheses import (
    LEGAL_CODES,
    Alone,
    Exchange,
    Expect,
    Experiment,
    Mechanism,
    SizeFacts,
    Status,
    answered_well,
    classify_alone,
    echo_story,
    frame_len,
    index_candidates,
    size_story,
)

NONE, POSE, TOLERANCE = int(Action.NONE), int(Action.POSE), int(Action.TOLERANCE)
CORE = (int(Action.NONE), int(Action.POSE), int(Action.REGISTER_POSE), int(Action.TOLERANCE))
CYCLES = (int(Action.CYCLE_ON), int(Action.CYCLE_OFF))
#: wrong index values tried at the position where acceptance changes
INDEX_TRIES = 6
#: requests sent on one connection to look for a per-connection limit
PER_CONNECTION = 30


def _valid(p: Prober, action: int) -> tuple[bytes, Expect]:
    return p.valid_request(action), Expect("valid", action, LEGAL_CODES.get(action, (0,)))


@dataclass
class Found:
    """What a family learnt: its experiment, the mechanisms it confirmed, and its stories' statuses."""

    experiment: Experiment
    mechanisms: list[Mechanism] = field(default_factory=list)
    stories: dict[str, tuple[Status, str]] = field(default_factory=dict)  # kind -> (status, why)
    alone: dict[int, Alone] = field(default_factory=dict)
    #: the two stories the family could not tell apart, in one line (an unconfirmed root cause's title)
    undecided: str = ""


# -- answers ---------------------------------------------------------------------------------------------
def answers(p: Prober, actions: Sequence[int]) -> Found:
    found = Found(Experiment("alone", "each valid request alone on a fresh connection, a NONE right after it"))
    none = p.valid_request(NONE)
    for action in actions:
        ex = p.exchange([p.valid_request(action), none])
        if ex is None or not ex.reached:
            break
        found.experiment.exchanges.append(ex)
        found.alone[action] = classify_alone(action, ex)
    tried = list(found.alone.values())
    for a in tried:
        frame, expect = _valid(p, a.action)
        if a.kind == "extra":
            found.mechanisms.append(_mech("extra-answer", {a.action}, found, ("A1",), [(frame, expect)],
                                          action=a.action, count=a.count))
        elif a.kind in ("missing", "silent"):
            if a.kind == "missing":  # the NONE behind it was answered: the connection still works
                found.mechanisms.append(_mech("missing-answer", {a.action}, found, ("A1", "T1"),
                                              [(frame, expect), _valid(p, NONE)], action=a.action))
        elif a.kind == "refused":
            found.mechanisms.append(_mech("refuses-valid", {a.action}, found, ("A1", "A3"), [(frame, expect)],
                                          action=a.action, error=a.error))
    story, value, wrong = echo_story(tried)
    if story == "echo-all":
        asked = ", ".join(titles.name(a) for a in sorted(wrong))
        first = min(wrong)
        found.mechanisms.append(_mech("echo-all", set(wrong) | ({value} if value is not None else set()), found, ("A2",),
                                      [_valid(p, first)], answered=value, asked=asked))
    elif story == "echo-one":
        for a in tried:
            if a.action in wrong:
                found.mechanisms.append(_mech("echo-one", {a.action}, found, ("A2",), [_valid(p, a.action)],
                                              action=a.action, answered=a.answered_action))
    kinds = {m.kind for m in found.mechanisms}
    for kind in ("extra-answer", "echo-one", "echo-all", "missing-answer", "refuses-valid"):
        found.stories[kind] = ((Status.CONFIRMED, "") if kind in kinds else
                               (Status.RULED_OUT, f"{len(tried)} requests alone: none shows it") if tried else
                               (Status.UNTESTED, "no exchange made"))
    found.experiment.finding = "; ".join(f"{titles.name(a.action)}: {a.kind}" + (f" x{a.count}" if a.count > 1 else "")
                                         for a in tried) or "no exchange made"
    return found


def _mech(kind: str, actions: set[int], found: Found, clauses: tuple[str, ...],
          repro: Sequence[tuple[bytes, Expect]], **detail: object) -> Mechanism:
    return Mechanism(kind, frozenset(actions), found.experiment.name, titles.of(kind, dict(detail)), clauses,
                     tuple(repro), dict(detail))


# -- size: count vs bytes vs index ------------------------------------------------------------------------
def _accepted(p: Prober, exp: Experiment, frame: bytes) -> bool | None:
    """The request, then a NONE: True answered 0000, False refused (an error, a close, or unanswered while
    the NONE behind it was answered), None when the box answered neither (out of time, gone)."""
    ex = p.exchange([frame, p.valid_request(NONE)], quiet=[True, False], settle=False)
    if ex is None or not ex.reached:
        return None
    exp.exchanges.append(ex)
    first, after = ex.reading(0), ex.reading(1)
    heard = list(first.answers) + list(after.answers)
    if first.closed and not first.answers:
        return False
    if not heard:
        return None
    if not first.answers and len(heard) == 1:
        return False  # only the NONE was answered
    return heard[0].error == 0


def size(p: Prober, usable: Sequence[int]) -> Found:
    """``usable``: the block actions answered right alone (one block) — the sizes worth measuring."""
    found = Found(Experiment("size", "255 blocks at each block size; the smallest refused count by bisection; "
                                     "wrong indexes where acceptance changes"))
    exp = found.experiment
    kinds = [a for a in (POSE, TOLERANCE) if a in usable]
    thresholds: dict[int, int | None] = {}
    which: dict[int, int] = {}
    for action in kinds:
        length = BLOCK_ACTIONS[action]
        top = _accepted(p, exp, block_request(p, action, 255))
        if top is None:
            return _untested(found)
        if top:
            thresholds[length] = None
            continue
        def accepts(count: int, action: int = action) -> bool | None:
            return _accepted(p, exp, block_request(p, action, count))

        n = smallest_refused(accepts, 1, 255)
        if n is None:
            return _untested(found)
        thresholds[length], which[length] = n, action
    if len(thresholds) < 1:
        return _untested(found)
    refused = {b: t for b, t in thresholds.items() if t is not None}
    facts = SizeFacts(thresholds)
    if refused:
        length, k = min(refused.items(), key=lambda kv: kv[1])
        action, tried = which[length], 0
        for value in index_candidates(k - 1, p.profile.first_index)[:INDEX_TRIES]:
            ok = _accepted(p, exp, block_request(p, action, k, k - 1, value))
            if ok is None:
                break
            tried += 1
            if ok:
                facts = SizeFacts(thresholds, (k, value), tried)
                break
        else:
            facts = SizeFacts(thresholds, None, tried)
        if facts.wrong_index_accepted is None:
            facts = SizeFacts(thresholds, None, tried)
    kind, detail, stories = size_story(facts)
    found.stories = {k: (s, why) for k, s, why in stories}
    exp.finding = ", ".join(f"{b}-byte blocks: " + (f"refused from {t}" if t else "255 accepted")
                            for b, t in sorted(thresholds.items()))
    if kind:
        found.mechanisms.append(_size_mechanism(p, kind, detail, which, thresholds, found))
    elif "max_bytes" in detail and 25 in refused:
        accepted = ", ".join(f"{b}-byte blocks are accepted up to 255 ({frame_len(255, b)} bytes)"
                             for b, t in sorted(thresholds.items()) if t is None) or "no other block size was tried"
        found.undecided = titles.size_undecided(refused[25], int(detail["max_bytes"]), int(detail["refused_bytes"]),
                                                accepted)
    return found


def _untested(found: Found) -> Found:
    found.stories = {k: (Status.UNTESTED, "out of time, or the box stopped answering")
                     for k in ("count-limit", "byte-limit", "index")}
    found.experiment.finding = "not finished"
    return found


def _size_mechanism(p: Prober, kind: str, detail: dict[str, object], which: dict[int, int],
                    thresholds: dict[int, int | None], found: Found) -> Mechanism:
    refused = {b: t for b, t in thresholds.items() if t is not None}
    length, k = min(refused.items(), key=lambda kv: kv[1])
    action = which[length]
    frame = block_request(p, action, k)
    if kind == "index":
        block, value = int(str(detail["block"])), int(str(detail["value"]))
        right = (p.profile.first_index + block - 1) & 0xFF
        wrong = block_request(p, action, block, block - 1, value)
        return _mech("index", set(BLOCK_ACTIONS), found, ("B3",), [(wrong, Expect("invalid", action))],
                     block=block, value=value, right=right, threshold=k)
    if kind == "byte-limit":
        names = {25: "a pose", 5: "a tolerance"}
        examples = " and ".join(f"{names.get(b, 'a request')} of {t} blocks ({frame_len(t, b)} bytes)"
                                for b, t in sorted(refused.items(), reverse=True))
        return _mech("byte-limit", set(BLOCK_ACTIONS), found, ("F5", "B5"),
                     [(frame, Expect("valid", action))], max_bytes=detail["max_bytes"], examples=examples,
                     refused_bytes=detail["refused_bytes"])
    per_type = bool(detail.get("per_type"))
    actions = {a for a, b in BLOCK_ACTIONS.items() if b == length} if per_type else set(BLOCK_ACTIONS)
    return _mech("count-limit", actions, found, ("B1", "B5"), [(frame, Expect("valid", action))],
                 threshold=k, per_action=action if per_type else None)


# -- state: after an error, in a cycle, per connection -------------------------------------------------------
def after_error(p: Prober, actions: Sequence[int], alone: dict[int, Alone]) -> Found:
    found = Found(Experiment("after-error", "a parse error (a pose whose first index is wrong), then a valid "
                                            "request, on one connection; vs the same request alone"))
    bad = block_request(p, POSE, 1, 0, (p.profile.first_index + 1) & 0xFF)
    for action in actions:
        if alone.get(action) is None or alone[action].kind != "ok":
            continue  # a defect of the request alone is not a leak
        frame, expect = _valid(p, action)
        ex = p.exchange([bad, frame, p.valid_request(NONE)], quiet=[True, False, False], settle=False)
        if ex is None or not ex.reached:
            break
        found.experiment.exchanges.append(ex)
        after = classify_alone(action, Exchange(ex.frames[1:], ex.readings[1:]))
        if ex.reading(0).answers and after.kind != "ok":
            refused = after.kind == "refused" or (after.kind == "malformed" and after.error not in (None, 0))
            what = {"refused": f"refuses (error {after.error or 0:04X})", "missing": "leaves unanswered",
                    "silent": "leaves unanswered", "closed": "closes the connection on",
                    "echo": "answers with the wrong action", "extra": "answers twice"}.get(
                "refused" if refused else after.kind, "mishandles")
            # one leak is enough: the next request is spoilt whatever its action (each try may cost time_out)
            found.mechanisms.append(_mech("state-leak", set(CORE) | set(actions), found, ("A1", "A3"),
                                          [(bad, Expect("invalid", POSE)), (frame, expect)], action=action, what=what))
            break
    found.stories["state-leak"] = (Status.CONFIRMED, "") if found.mechanisms else (
        (Status.RULED_OUT, "valid requests after an error answered as alone") if found.experiment.exchanges
        else (Status.UNTESTED, "no exchange made"))
    found.experiment.finding = found.mechanisms[0].title if found.mechanisms else "no leak"
    return found


def cycle(p: Prober, alone: dict[int, Alone]) -> Found:
    found = Found(Experiment("cycle", "a pose inside a cycle (CycleOff, CycleOn, pose, CycleOff) vs alone"))
    on, off = _valid(p, int(Action.CYCLE_ON)), _valid(p, int(Action.CYCLE_OFF))
    pose = _valid(p, POSE)
    started, inside = False, None
    for _ in range(2):  # a box may refuse its first CycleOn (0001, not ready: S2): once more
        ex = p.exchange([off[0], on[0], pose[0], off[0]], settle=False)
        if ex is None or not ex.reached:
            break
        found.experiment.exchanges.append(ex)
        began = ex.reading(1).answers
        started, inside = bool(began) and began[0].error == 0, ex.reading(2)
        if started:
            break
    if inside is None:
        found.stories["cycle-dependent"] = (Status.UNTESTED, "no exchange made")
        return found
    inside_ok = answered_well(POSE, inside.answers)
    alone_ok = alone.get(POSE) is not None and alone[POSE].kind == "ok"
    if started and alone_ok != inside_ok and POSE in alone:
        failing_refused = (inside.answers and inside.answers[0].error) if alone_ok else alone[POSE].kind == "refused"
        what = gettext("Refuses") if failing_refused else gettext("Mishandles")
        shown = [off, on, pose, off] if alone_ok else [off, pose]  # the pose where it is mishandled
        found.mechanisms.append(_mech("cycle-dependent", {POSE}, found, ("S3",), shown,
                                      action=POSE, inside=not inside_ok, what=what))
    found.stories["cycle-dependent"] = (Status.CONFIRMED, "") if found.mechanisms else (
        (Status.RULED_OUT, "a pose is answered the same inside a cycle and alone") if started
        else (Status.UNTESTED, "the cycle did not start (CycleOn not answered 0000)"))
    return found


def per_connection(p: Prober) -> Found:
    found = Found(Experiment("per-connection", f"{PER_CONNECTION} NONE requests on one connection"))
    none = _valid(p, NONE)
    ex = p.exchange([none[0]] * PER_CONNECTION, settle=False, stop_silent=True)
    if ex is None or not ex.reached:
        found.stories["connection-count"] = (Status.UNTESTED, "no exchange made")
        return found
    found.experiment.exchanges.append(ex)
    bad = next((i for i in range(PER_CONNECTION) if none[1].broken_by(ex.reading(i))), None)
    if bad is not None and bad > 0:
        found.mechanisms.append(_mech("connection-count", {NONE, POSE, TOLERANCE, int(Action.REGISTER_POSE)}, found,
                                      ("A1",), [none] * (bad + 1), n=bad))
    found.stories["connection-count"] = (Status.CONFIRMED, "") if found.mechanisms else (
        Status.RULED_OUT, f"{PER_CONNECTION} requests on one connection all answered")
    return found

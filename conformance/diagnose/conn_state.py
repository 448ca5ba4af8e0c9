"""Connection state: a close the catalogue saw in place of an answer, told apart by what state triggered it.

A case that closes the connection "instead of answering CycleOff" may hit a box that closes at CycleOff, or one
that closes any connection left silent for a few seconds (the robot's command connection is silent for a whole
trajectory between CycleOn and CycleOff), or one that closes every connection some seconds after it opened. The
family asks, each on a fresh connection (every wait bounded by the phase's deadline):

* the request at once: from the ``alone`` experiment (answered, and the NONE behind it answered: the request
  alone does not close the connection);
* idle: a NONE answered, then silence: when does the box close it (``idle_s``, within :data:`IDLE_MAX_S`)?
* busy: a NONE every :func:`pace` seconds for longer than ``idle_s``: kept open (the close depends on the
  idle time) or closed as well (the connection's age)?

:func:`judge` is the pure verdict on those measurements.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass

from ..harness.client import Answer, Closed, Malformed, Silence
from ..harness.target import Unreachable
from ..model.verdicts import CaseResult
from ..protocol import Action
from . import conn_titles
from .experiments import Prober, heard
from .families import Found
from .hypotheses import Exchange, Experiment, Heard, Mechanism, Reading, Status

#: the longest silence waited for a close (the robot's command connection is silent for a trajectory: seconds)
IDLE_MAX_S = 8.0
#: what must be left of the phase's budget after the idle wait (for the busy connection and the rest)
RESERVE_S = 5.0
#: the busy connection is kept this many times the idle close's time
BUSY_FACTOR = 1.5
KINDS = ("idle-close", "age-close")
NONE = int(Action.NONE)


@dataclass(frozen=True)
class Measured:
    """What the idle and busy connections showed: seconds to the idle close (None: open for ``waited_s``), how
    long the busy connection was kept answering, whether it was closed, and the request sent at once."""

    idle_s: float | None
    waited_s: float
    busy_s: float = 0.0
    busy_closed: bool = False
    prompt_action: int | None = None  # the request the catalogue saw closed, sent at once on a fresh connection
    prompt_kept: bool | None = None  # ... answered, and the connection kept open (None: not tried)


def pace(idle_s: float) -> float:
    """The gap between the busy connection's requests: a third of the idle time (0.1–1 s)."""
    return min(1.0, max(0.1, idle_s / 3.0))


def judge(m: Measured) -> tuple[str, dict[str, tuple[Status, str]]]:
    """The confirmed kind ("" for none) and each story's status (idle, age, the request itself)."""
    stories: dict[str, tuple[Status, str]] = {}
    if m.prompt_kept is not None:
        stories["closes-at-request"] = (
            (Status.RULED_OUT, "sent at once on a fresh connection: answered, and the connection kept open")
            if m.prompt_kept else (Status.CONSISTENT, "sent at once on a fresh connection, the connection was closed"))
    if m.idle_s is None:
        why = f"an idle connection was kept open {m.waited_s:.1f} s"
        stories.update({"idle-close": (Status.RULED_OUT, why), "age-close": (Status.RULED_OUT, why)})
        return "", stories
    idle = f"an idle connection closed after {m.idle_s:.1f} s"
    if m.busy_closed:
        if m.busy_s < 0.5 * m.idle_s:  # closed much sooner than the idle one: neither story fits
            why = f"{idle}; a busy one closed after {m.busy_s:.1f} s"
            stories.update({"idle-close": (Status.CONSISTENT, why), "age-close": (Status.CONSISTENT, why)})
            return "", stories
        why = f"{idle}, and one carrying a NONE every {pace(m.idle_s):.1f} s closed after {m.busy_s:.1f} s too"
        stories.update({"age-close": (Status.CONFIRMED, why), "idle-close": (Status.RULED_OUT, why)})
        return "age-close", stories
    if m.busy_s <= m.idle_s:  # the busy connection was not kept long enough to tell (out of time)
        why = f"{idle}; a busy one was kept only {m.busy_s:.1f} s"
        stories.update({"idle-close": (Status.CONSISTENT, why), "age-close": (Status.CONSISTENT, why)})
        return "", stories
    why = f"{idle}, while one carrying a NONE every {pace(m.idle_s):.1f} s stayed open {m.busy_s:.1f} s"
    stories.update({"idle-close": (Status.CONFIRMED, why), "age-close": (Status.RULED_OUT, why)})
    return "idle-close", stories


def title(kind: str, m: Measured) -> str:
    assert m.idle_s is not None
    if kind == "age-close":
        return conn_titles.age_close(m.idle_s, m.busy_s)
    return conn_titles.idle_close(m.idle_s, m.busy_s, pace(m.idle_s), m.prompt_action if m.prompt_kept else None)


def prompt_kept(alone: Experiment | None, action: int) -> bool | None:
    """From the ``alone`` experiment: ``action`` answered on a fresh connection and the NONE behind it answered."""
    for ex in (alone.exchanges if alone is not None else []):
        if ex.frames and len(ex.frames[0]) > 5 and ex.frames[0][5] == action:
            return bool(ex.reading(0).answers) and bool(ex.reading(1).answers) and not ex.reading(1).closed
    return None


def closed_at_once(alone: Experiment | None) -> bool:
    """Did a request alone (or the NONE behind it) already find the connection closed? (another family's story)"""
    return any(r.closed for ex in (alone.exchanges if alone is not None else []) for r in ex.readings)


def closed_instead_of(cases: Sequence[CaseResult]) -> int | None:
    """The action a closing root cause's first case expected an answer to (its signature's subject)."""
    for case in cases:
        sig = case.signature
        if sig is not None and sig.subject:
            try:
                return int(Action[sig.subject])
            except KeyError:
                continue
    return None


# -- live ---------------------------------------------------------------------------------------------------
def _idle(p: Prober, exp: Experiment, wait_s: float) -> float | None | bool:
    """A NONE answered, then silence for at most ``wait_s``: seconds to the close, None when kept open, False
    when the NONE was not answered (nothing to measure)."""
    none = p.valid_request(NONE)
    p.count += 1
    try:
        conn = p.dialer.dial("diagnose idle")
    except Unreachable:
        return False
    try:
        if not conn.send(none, "diagnose idle"):
            return False
        first = conn.receive(p.dialer.by())
        if not isinstance(first, (Answer, Malformed)):
            return False
        start = time.monotonic()
        heard = [_heard(first)]
        while True:
            outcome = conn.receive(start + wait_s)
            if isinstance(outcome, Closed):
                idle = round(time.monotonic() - start, 2)
                exp.exchanges.append(Exchange((none,), (Reading(tuple(heard), True),)))
                return idle
            if isinstance(outcome, Silence):
                exp.exchanges.append(Exchange((none,), (Reading(tuple(heard), False),)))
                return None
            heard.append(_heard(outcome))
    finally:
        conn.close("diagnose idle")


def _busy(p: Prober, exp: Experiment, idle_s: float) -> tuple[float, bool]:
    """A NONE every :func:`pace` seconds for :data:`BUSY_FACTOR` times ``idle_s``: (seconds kept, closed?)."""
    none, gap = p.valid_request(NONE), pace(idle_s)
    p.count += 1
    try:
        conn = p.dialer.dial("diagnose busy")
    except Unreachable:
        return 0.0, False
    start, readings = time.monotonic(), []
    try:
        while time.monotonic() - start < BUSY_FACTOR * idle_s and p.left() > gap + 0.5:
            if not conn.send(none, "diagnose busy"):
                readings.append(Reading((), True))
                break
            outcome = conn.receive(p.dialer.by())
            closed = isinstance(outcome, Closed)
            readings.append(Reading(() if isinstance(outcome, (Closed, Silence)) else (_heard(outcome),), closed))
            if closed or isinstance(outcome, Silence):
                break
            after = conn.receive(time.monotonic() + gap)  # the gap: a close in it ends the connection
            if isinstance(after, Closed):
                readings.append(Reading((), True))
                break
    finally:
        conn.close("diagnose busy")
    kept = round(time.monotonic() - start, 2)
    exp.exchanges.append(Exchange(tuple(none for _ in readings), tuple(readings)))
    return kept, any(r.closed for r in readings)


def _heard(outcome: object) -> Heard:
    if isinstance(outcome, (Answer, Malformed)):
        return heard(outcome)
    return Heard(None, None, b"", "unexpected outcome")


def run(p: Prober, alone: Experiment | None, action: int | None) -> Found:
    """The idle and busy connections (``action``: the request the catalogue saw closed, for the story that the
    request itself closes it)."""
    exp = Experiment("connection-state", "a NONE answered then silence: when does the box close the connection? "
                                         "and a connection carrying a NONE every third of that time: kept open?")
    found = Found(exp)
    kept = prompt_kept(alone, action) if action is not None else None
    wait_s = min(IDLE_MAX_S, p.left() - RESERVE_S)
    if wait_s < 1.0:
        found.stories["idle-close"] = (Status.UNTESTED, "out of time")
        return found
    idle = _idle(p, exp, wait_s)
    if idle is False:
        found.stories["idle-close"] = (Status.UNTESTED, "a NONE on a fresh connection was not answered")
        return found
    m = Measured(idle if isinstance(idle, float) else None, wait_s, prompt_action=action, prompt_kept=kept)
    if m.idle_s is not None:
        busy_s, busy_closed = _busy(p, exp, m.idle_s)
        m = Measured(m.idle_s, wait_s, busy_s, busy_closed, action, kept)
    kind, found.stories = judge(m)
    exp.finding = "; ".join(dict.fromkeys(why for _, why in found.stories.values()))
    if kind:
        detail = {"idle_s": m.idle_s, "busy_s": m.busy_s, "title": title(kind, m)}
        # no repro file: a time on the wire is no frame a vector can hold
        found.mechanisms.append(Mechanism(kind, frozenset(), exp.name, str(detail["title"]), ("S1", "S4"), (),
                                          detail))
    return found

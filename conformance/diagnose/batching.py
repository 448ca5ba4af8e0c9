"""A box that answers no NONE within time_out: silent, late, or holding its answers back until several are due?

The session found the box answering no NONE request (``unresponsive``). Three stories fit that from the outside:
the box never answers (or speaks another profile: PROFILE-01 says which); it answers every request late (a slow
box); or it writes answers in batches, holding a lone answer until more are pending or a timer fires, so a
robot's lone request waits while a stream looks almost fine. The experiments, each on a fresh connection:

1. 16 NONE requests in one write, waited for :data:`BATCH_WAIT_S`: a box that answers nothing at all costs no
   more than that (nothing else is tried);
2. one NONE, waited for up to :data:`LATE_FACTOR` × time_out (cut to what is left of the phase): when it is
   answered, how late;
3. when it came late, NONE requests sent together in one write, 2, 4 and 8 of them, each trial waited for
   :data:`BATCH_WAIT_S`: the smallest count answered at once is the batch (then narrowed between the last
   count held back and it).

:func:`judge` is the pure verdict; the title says what was measured and the story it confirms.
"""

from __future__ import annotations

import time
from collections.abc import Iterable
from dataclasses import dataclass

from ..harness.client import Answer, Closed, Malformed, TcpConnection
from ..harness.target import Unreachable
from ..i18n import gettext
from ..model.verdicts import RootCause
from ..protocol import Action
from .experiments import Prober, heard
from .hypotheses import Exchange, Experiment, Hypothesis, Reading, Status

#: a lone NONE is waited for up to this many time_outs
LATE_FACTOR = 2.0
#: a batch trial's wait: answers written at once come within it
BATCH_WAIT_S = 1.0
#: the batch sizes tried, in order
COUNTS = (2, 4, 8, 16)
KIND = "unresponsive"


@dataclass(frozen=True)
class Measured:
    """A lone NONE's latency (None: not answered within the wait), and per count sent together, how many
    answers came within :data:`BATCH_WAIT_S`."""

    lone_s: float | None
    time_out_s: float
    together: tuple[tuple[int, int], ...] = ()


def judge(m: Measured) -> tuple[str, int | None]:
    """("batch", n): a lone NONE answered late and n sent together answered at once; ("late", None): answered late
    whatever; ("silent", None): not answered within the wait; ("", None): answered in time (nothing to say)."""
    if m.lone_s is None:
        return "silent", None
    if m.lone_s <= m.time_out_s:
        return "", None
    prompt = [n for n, got in m.together if got >= n]
    return ("batch", min(prompt)) if prompt else ("late", None)


def _collect(conn: TcpConnection, n: int, wait_s: float) -> tuple[list[Answer | Malformed], bool, float]:
    """Up to ``n`` answers within ``wait_s``: (answers, closed, seconds to the last one)."""
    start = time.monotonic()
    got: list[Answer | Malformed] = []
    while len(got) < n:
        outcome = conn.receive(start + wait_s)
        if isinstance(outcome, (Answer, Malformed)):
            got.append(outcome)
            continue
        return got, isinstance(outcome, Closed), time.monotonic() - start
    return got, False, time.monotonic() - start


def _trial(p: Prober, exp: Experiment, n: int, wait_s: float) -> tuple[int, float] | None:
    """``n`` NONE in one write on a fresh connection: (answers within ``wait_s``, seconds to the last)."""
    none = p.valid_request(int(Action.NONE))
    try:
        conn = p.dialer.dial(f"diagnose batching: {n} NONE together")
    except Unreachable:
        return None
    p.count += 1
    try:
        conn.send(none * n, f"diagnose batching: {n} NONE requests in one write")
        got, closed, took = _collect(conn, n, wait_s)
    finally:
        conn.close("diagnose batching")
    exp.exchanges.append(Exchange((none * n,), (Reading(tuple(heard(o) for o in got), closed),), together=True))
    return len(got), took


def measure(p: Prober, exp: Experiment, time_out_s: float) -> Measured:
    """The largest batch first (a box that answers nothing costs :data:`BATCH_WAIT_S`, not a long wait), then, when
    anything came, a lone NONE waited for past time_out, then the smaller counts."""
    if p.left() < BATCH_WAIT_S + time_out_s + 1.0:
        return Measured(None, time_out_s)
    most = _trial(p, exp, COUNTS[-1], BATCH_WAIT_S)
    if most is None or most[0] == 0:
        return Measured(None, time_out_s, ((COUNTS[-1], 0),) if most is not None else ())
    lone = _trial(p, exp, 1, min(LATE_FACTOR * time_out_s, p.left() - 1.0))
    if lone is None or lone[0] == 0:
        return Measured(None, time_out_s, ((COUNTS[-1], most[0]),))
    lone_s = lone[1]
    if lone_s <= time_out_s:
        return Measured(lone_s, time_out_s)
    together: list[tuple[int, int]] = [(COUNTS[-1], most[0])]
    _until_prompt(p, exp, COUNTS[:-1], together)
    prompt = [n for n, got in together if got >= n]
    held = [n for n, got in together if got < n]
    if prompt and held:  # narrowed between the largest count held back and the smallest answered at once
        _until_prompt(p, exp, range(max(held) + 1, min(prompt)), together)
    return Measured(lone_s, time_out_s, tuple(together))


def _until_prompt(p: Prober, exp: Experiment, counts: Iterable[int], together: list[tuple[int, int]]) -> None:
    """Each count sent together in turn, until one is answered at once (appended to ``together``)."""
    for n in counts:
        if p.left() < BATCH_WAIT_S + 0.5:
            return
        got = _trial(p, exp, n, BATCH_WAIT_S)
        if got is None:
            return
        together.append((n, got[0]))
        if got[0] >= n:
            return


def title_of(kind: str, m: Measured, n: int | None) -> str:
    late, limit = f"{m.lone_s or 0:.1f}", f"{m.time_out_s:.1f}"
    if kind == "batch":
        return gettext("Holds its answers back until {n} are due: a lone NONE is answered only after {late} s, past "
                       "time_out ({limit} s), while {n} NONE requests sent together are answered at once (a flush "
                       "timer and a batch of {n}?): T1/A1 ask for each answer within time_out — write each answer "
                       "when it is ready").format(n=n, late=late, limit=limit)
    return gettext("Answers a NONE only after {late} s, past time_out ({limit} s), alone or with others sent "
                   "together: T1 asks for an answer within time_out — answer at once").format(late=late, limit=limit)


def run(p: Prober, cause: RootCause, time_out_s: float) -> None:
    """The experiments; a late or batched answer re-titles ``cause`` (confirmed), a silence leaves it as read."""
    exp = Experiment("batching", "a lone NONE waited for past time_out; then NONE requests sent together (2, 4, 8, 16): "
                                 "answered at once when several are due?")
    m = measure(p, exp, time_out_s)
    kind, n = judge(m)
    exp.finding = (f"lone NONE: {'not answered' if m.lone_s is None else f'{m.lone_s:.2f} s'}; together: "
                   + ", ".join(f"{k} sent, {got} answered within {BATCH_WAIT_S:.0f} s" for k, got in m.together))
    if kind not in ("batch", "late"):
        return
    stories = [Hypothesis("batch", gettext("answers held back until several are due"),
                          Status.CONFIRMED if kind == "batch" else Status.RULED_OUT, exp.name),
               Hypothesis("late", gettext("every answer late"), Status.CONFIRMED if kind == "late" else Status.RULED_OUT,
                          exp.name),
               Hypothesis("silent", gettext("never answers"), Status.RULED_OUT, exp.name)]
    original = cause.title
    cause.title, cause.clauses = title_of(kind, m, n), ("T1", "A1")
    cause.diagnosis = {"confirmed": True, "mechanism": f"answers-{kind}", "catalogue_title": original,
                       "detail": {"lone_s": m.lone_s, "together": [list(t) for t in m.together], "batch": n},
                       "hypotheses": [h.to_dict() for h in stories], "experiments": [exp.to_dict()]}

"""How many connections at once: a box that stops accepting while some number are open, and accepts again once
they close (R5: idle connections held open must not stop it serving others), told apart from one that never
frees closed connections (S5) and from one that closes for other reasons (:mod:`.conn_peers`, :mod:`.conn_state`).

The experiment opens connections one at a time, each asked a NONE and kept open, up to :data:`MAX_OPEN`; the
first one refused, closed or left unanswered gives the limit (how many were open then). Every connection is then
closed and a fresh one asked a NONE: answered, the limit is on connections held open; not answered, the box
did not free them (or died) and the story stays open. :func:`judge` is the pure verdict.
"""

from __future__ import annotations

from dataclasses import dataclass

from ..harness.client import Answer, Malformed, TcpConnection
from ..harness.target import Unreachable
from ..protocol import Action
from . import conn_titles
from .experiments import Prober
from .families import Found
from .hypotheses import Experiment, Mechanism, Status

#: connections held open at most (R5 speaks of hundreds; a small box's table is often 4–32)
MAX_OPEN = 48
KIND = "open-limit"
NONE = int(Action.NONE)


@dataclass(frozen=True)
class Held:
    """``refused_at``: how many were open when the next was refused (None: :data:`MAX_OPEN` all answered);
    ``after``: a fresh connection's NONE answered once they were all closed (None: not tried)."""

    refused_at: int | None
    after: bool | None
    tried: int


def judge(h: Held) -> tuple[str, tuple[Status, str]]:
    if h.refused_at is None:
        return "", (Status.RULED_OUT, f"{h.tried} connections held open at once, each answered")
    if h.refused_at < 2:  # not even a second connection: the session's one-connection check tells that story
        return "", (Status.UNTESTED, "a second connection was not served")
    if h.after:
        return KIND, (Status.CONFIRMED, f"with {h.refused_at} connections open the next was not served; once they "
                                        "closed a fresh one was answered")
    return "", (Status.CONSISTENT, f"with {h.refused_at} connections open the next was not served, and a fresh one "
                                   "was not served after they closed either")


def _answered(p: Prober, conn: TcpConnection) -> bool:
    if not conn.send(p.valid_request(NONE), "diagnose open-limit"):
        return False
    return isinstance(conn.receive(p.dialer.by()), (Answer, Malformed))


def measure(p: Prober) -> Held:
    held: list[TcpConnection] = []
    refused_at: int | None = None
    p.count += 1
    try:
        for _ in range(MAX_OPEN):
            if p.left() < p.dialer.wait_s() + 1.0:
                return Held(None, None, len(held))
            try:
                conn = p.dialer.dial("diagnose open-limit")
            except Unreachable:
                refused_at = len(held)
                break
            held.append(conn)
            if not _answered(p, conn):
                refused_at = len(held) - 1
                break
    finally:
        for conn in held:
            conn.close("diagnose open-limit")
    if refused_at is None:
        return Held(None, None, len(held))
    try:
        fresh = p.dialer.dial("diagnose open-limit: after the others closed")
    except Unreachable:
        return Held(refused_at, False, len(held))
    try:
        return Held(refused_at, _answered(p, fresh), len(held))
    finally:
        fresh.close("diagnose open-limit")


def run(p: Prober) -> Found:
    exp = Experiment("open-limit", f"connections opened one at a time and held open (at most {MAX_OPEN}), each asked "
                                   "a NONE; then all closed and a fresh one asked a NONE")
    found = Found(exp)
    held = measure(p)
    kind, story = judge(held)
    found.stories[KIND] = story
    exp.finding = story[1]
    if kind and held.refused_at is not None:
        title = conn_titles.open_limit(held.refused_at)
        found.mechanisms.append(Mechanism(KIND, frozenset(), exp.name, title, ("R5", "S4"), (),
                                          {"open": held.refused_at, "title": title}))
    return found


def decided(found: Found) -> bool:
    return any(m.kind == KIND for m in found.mechanisms)

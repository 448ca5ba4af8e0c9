"""Another connection's doing: does a second connection, or a cycle request on it, close the first?

The robot holds two connections at once (S4: the command connection and Send_Pos's stream), opened one after
the other, and sends CycleOn and CycleOff on one while the other stays open. A box that keeps only its newest
connection, or that ends every connection at CycleOff, closes a connection the robot still uses; the catalogue
sees a close "instead of answering" on the first. The experiment: connection A (a NONE answered), then on a
second connection B in turn a NONE, a CycleOn, a CycleOff, a pose and B's close (the stream ended), each
followed by a NONE on A: the first step after which A is found closed is the state that closes it. :func:`judge` is the pure verdict.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

from ..harness.client import Answer, Closed, Malformed, TcpConnection
from ..harness.target import Unreachable
from ..protocol import Action
from . import conn_titles
from .experiments import Prober, heard
from .families import Found
from .hypotheses import Exchange, Experiment, Mechanism, Reading, Status

NONE, ON, OFF, POSE = int(Action.NONE), int(Action.CYCLE_ON), int(Action.CYCLE_OFF), int(Action.POSE)
#: not an action: connection B, after it sent a pose (a stream), closes (Send_Pos_Off)
STREAM_CLOSED = -1
#: what is done on connection B before A is asked again ("open": B connected and a NONE answered on it)
STEPS = (NONE, ON, OFF, STREAM_CLOSED)
KIND = "peer-close"
#: a step on B longer than this leaves A idle long enough that an idle close may explain a close of A
SLOW_STEP_S = 1.0


@dataclass(frozen=True)
class Steps:
    """After each step on B: its action, whether A still answered a NONE (True, False: closed, None: silent), and
    how long A had been idle by then (seconds)."""

    after: tuple[tuple[int, bool | None, float], ...]
    #: after A was found closed at B's close: did A, with a new B that sent a pose and stayed open, survive as
    #: long (True: B's close did it; False or None: idle time may explain it)
    control: bool | None = None


def judge(s: Steps) -> tuple[int | None, tuple[Status, str]]:
    """The step on B after which A was first found closed (None: none), and the story's status."""
    for action, alive, idle_s in s.after:
        if alive is False and idle_s > SLOW_STEP_S:  # A was idle long enough for an idle close to explain it
            return None, (Status.CONSISTENT, f"connection A closed after {_what(action)} on connection B, but it had "
                                             f"been idle {idle_s:.1f} s by then")
        if alive is False and action == STREAM_CLOSED and s.control is not True:
            return None, (Status.CONSISTENT, f"connection A closed after {_what(action)}, but also (or untested) "
                                             "when B stayed open as long: idle time may explain it")
        if alive is False:
            return action, (Status.CONFIRMED, f"connection A closed after {_what(action)} on connection B")
        if alive is None:
            return None, (Status.UNTESTED, f"connection A silent after {_what(action)} on connection B")
    if not s.after:
        return None, (Status.UNTESTED, "no exchange made")
    return None, (Status.RULED_OUT, "connection A kept answering while B opened and ran a cycle")


def _what(action: int) -> str:
    if action == STREAM_CLOSED:
        return "a pose, then the close of connection B (a stream ended)"
    return "a connection opened (a NONE answered)" if action == NONE else f"{'CycleOn' if action == ON else 'CycleOff'}"


def _ask(p: Prober, conn: TcpConnection, frame: bytes) -> tuple[Reading, bool | None]:
    if not conn.send(frame, "diagnose peers"):
        return Reading((), True), False
    outcome = conn.receive(p.dialer.by())
    if isinstance(outcome, Closed):
        return Reading((), True), False
    if isinstance(outcome, (Answer, Malformed)):
        return Reading((heard(outcome),)), True
    return Reading(), None


def measure(p: Prober, exp: Experiment) -> Steps:
    """Connection A, then the :data:`STEPS` on connection B, A asked a NONE after each."""
    none = p.valid_request(NONE)
    if p.left() < 2 * p.dialer.wait_s() + 1.0:
        return Steps(())
    p.count += 1
    conns: list[TcpConnection] = []
    frames: list[bytes] = []
    readings: list[Reading] = []
    after: list[tuple[int, bool | None, float]] = []
    try:
        conns.append(p.dialer.dial("diagnose peers A"))
        first, ok = _ask(p, conns[0], none)
        frames.append(none)
        readings.append(first)
        if not ok:
            return Steps(())
        conns.append(p.dialer.dial("diagnose peers B"))
        for action in STEPS:
            since = time.monotonic()  # A's last answer (near enough: B's dial is quick)
            sent = p.valid_request(POSE if action == STREAM_CLOSED else action)
            on_b, _ = _ask(p, conns[1], sent)
            if action == STREAM_CLOSED:
                conns[1].close("diagnose peers: the stream ends (Send_Pos_Off)")
                time.sleep(min(0.2, p.dialer.wait_s()))  # the box sees B's close before A is asked
            idle_s = round(time.monotonic() - since, 2)
            on_a, alive = _ask(p, conns[0], none)
            frames += [sent, none]
            readings += [on_b, on_a]
            after.append((action, alive, idle_s))
            if alive is not True:
                break
        if after and after[-1][0] == ON:
            conns[1].send(p.valid_request(OFF), "diagnose peers: leave no cycle on")
    except Unreachable:
        pass
    finally:
        for conn in conns:
            conn.close("diagnose peers")
        exp.exchanges.append(Exchange(tuple(frames), tuple(readings)))
    if after and after[-1][0] == STREAM_CLOSED and after[-1][1] is False:
        return Steps(tuple(after), _control(p, exp, after[-1][2]))
    return Steps(tuple(after))


def _control(p: Prober, exp: Experiment, idle_s: float) -> bool | None:
    """A fresh A, a fresh B that sends a pose and stays open, A asked after ``idle_s``: does A survive?"""
    none, pose = p.valid_request(NONE), p.valid_request(POSE)
    if p.left() < 2 * p.dialer.wait_s() + idle_s:
        return None
    conns: list[TcpConnection] = []
    try:
        conns.append(p.dialer.dial("diagnose peers: control A"))
        first, ok = _ask(p, conns[0], none)
        if not ok:
            return None
        since = time.monotonic()
        conns.append(p.dialer.dial("diagnose peers: control B, left open"))
        on_b, _ = _ask(p, conns[1], pose)
        time.sleep(max(0.0, idle_s - (time.monotonic() - since)))
        on_a, alive = _ask(p, conns[0], none)
        exp.exchanges.append(Exchange((none, pose, none), (first, on_b, on_a)))
        return alive
    except Unreachable:
        return None
    finally:
        for conn in conns:
            conn.close("diagnose peers: control")


def run(p: Prober) -> Found:
    exp = Experiment("peers", "connection A (a NONE answered), then on connection B a NONE, a CycleOn, a CycleOff, "
                              "a pose and B's close, each followed by a NONE on A: does anything on B close A?")
    found = Found(exp)
    steps = measure(p, exp)
    action, story = judge(steps)
    found.stories[KIND] = story
    exp.finding = story[1]
    if action is not None:
        title = conn_titles.peer_close(action)
        found.mechanisms.append(Mechanism(KIND, frozenset(), exp.name, title, ("S4", "S1"), (),
                                          {"after": action, "title": title}))
    return found


def decided(found: Found) -> bool:
    return any(m.kind == KIND for m in found.mechanisms)

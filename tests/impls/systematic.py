"""Systematic planted defects for the root-cause benchmark: one mechanism each, on a random legal base.

Each defect declares the clause it breaks and the *mechanism* the first root cause must name
(``conformance/diagnose`` kinds: count-limit, byte-limit, index, extra-answer, echo-one, echo-all,
missing-answer, refuses-valid, state-leak, cycle-dependent, connection-count). Many are chosen
so that two stories fit the catalogue's verdicts (a 7-bit index counter refuses every valid
request of 129 blocks like a count limit would; a pose answered twice looks like the action
never echoed; a frame limit in bytes looks like an index judged wrongly).

:func:`decide` wraps the box's own policy (:func:`tests.impls.policy.decide`): it is given the
policy's decision function and answer encoder, so this module imports nothing of the policy.
Sans-I/O; the per-connection state (:class:`ConnState`) lives in the box's connection loop.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import Any

from . import wire_format as wire
from .framers import Close, Event, Frame

POSE, REG, TOL, NONE, ON, OFF = wire.POSE, wire.REG_POSE, wire.TOLERANCE, wire.NONE, wire.CYCLE_ON, wire.CYCLE_OFF


@dataclass(frozen=True)
class Planted:
    clause: str
    mechanism: str  # the diagnose kind the headline must name
    description: str
    rule: tuple[Any, ...]  # what the box does: ("count", n), ("bytes", n), ("index", fn name) ...


def _p(clause: str, mechanism: str, description: str, *rule: Any) -> Planted:
    return Planted(clause, mechanism, description, tuple(rule))


SYSTEMATIC: dict[str, Planted] = {
    # size: count vs bytes vs index
    "signed-count": _p("B5", "count-limit", "refuses every request of 128 or more blocks (count read as signed)",
                       "count", 128, "error"),
    "count-over-100": _p("B5", "count-limit", "refuses every request of more than 100 blocks", "count", 101, "error"),
    "count-64": _p("B5", "count-limit", "refuses every request of 64 or more blocks", "count", 64, "error"),
    "count-over-200": _p("B5", "count-limit", "refuses every request of more than 200 blocks", "count", 201, "error"),
    "count-150-close": _p("B5", "count-limit", "closes the connection on a request of 150 or more blocks",
                          "count", 150, "close"),
    "frame-1024": _p("F5", "byte-limit", "refuses every frame longer than 1024 bytes", "bytes", 1024, "error"),
    "frame-512": _p("F5", "byte-limit", "refuses every frame longer than 512 bytes", "bytes", 512, "error"),
    "frame-768": _p("F5", "byte-limit", "refuses every frame longer than 768 bytes", "bytes", 768, "error"),
    "frame-1200": _p("F5", "byte-limit", "refuses every frame longer than 1200 bytes", "bytes", 1200, "error"),
    "frame-1024-silent": _p("F5", "byte-limit", "drops every frame longer than 1024 bytes unanswered",
                            "bytes", 1024, "silent"),
    "tolerance-count-50": _p("B5", "count-limit", "refuses tolerance requests of more than 50 blocks (poses fine)",
                             "count-of", 51, TOL),
    "pose-count-30": _p("B5", "count-limit", "refuses pose and register pose requests of more than 30 blocks",
                        "count-of", 31, POSE, REG),
    "index-mod-16": _p("B3", "index", "checks block indexes with a 4-bit counter", "index", 0x0F),
    "index-mod-32": _p("B3", "index", "checks block indexes with a 5-bit counter", "index", 0x1F),
    "index-mod-64": _p("B3", "index", "checks block indexes with a 6-bit counter", "index", 0x3F),
    "index-mod-128": _p("B3", "index", "checks block indexes with a 7-bit counter (looks like a count limit)",
                        "index", 0x7F),
    "index-mod-100": _p("B3", "index", "expects the index to restart at 0 after 99", "index", 100),
    # answers: echo one vs every vs shifted
    "pose-twice": _p("A1", "extra-answer", "answers every pose twice", "twice", POSE),
    "tolerance-twice": _p("A1", "extra-answer", "answers every tolerance request twice", "twice", TOL),
    "none-twice": _p("A1", "extra-answer", "answers every NONE twice", "twice", NONE),
    "register-twice": _p("A1", "extra-answer", "answers every register pose twice", "twice", REG),
    "register-as-23": _p("A2", "echo-one", "answers register pose (24) with action 23", "as", REG, POSE),
    "tolerance-as-24": _p("A2", "echo-one", "answers tolerance (25) with action 24", "as", TOL, REG),
    "cycle-off-as-01": _p("A2", "echo-one", "answers CycleOff (02) with action 01", "as", OFF, ON),
    "echo-00-all": _p("A2", "echo-all", "answers every request with action 00", "all", NONE),
    "echo-23-all": _p("A2", "echo-all", "answers every request with action 23", "all", POSE),
    "tolerance-missing": _p("A1", "missing-answer", "never answers a tolerance request", "missing", TOL),
    "register-missing": _p("A1", "missing-answer", "never answers a register pose", "missing", REG),
    "register-refused": _p("A3", "refuses-valid", "answers every valid register pose 1001", "refuse", REG, 0x1001),
    "tolerance-refused": _p("A3", "refuses-valid", "answers every valid tolerance request 1002", "refuse", TOL, 0x1002),
    # state: after an error, in a cycle, per connection
    "error-leaks": _p("A1", "state-leak", "after an error answer, answers the next request with that error too",
                       "sticky"),
    "swallow-after-error": _p("A1", "state-leak", "after an error answer, leaves the next request unanswered",
                              "swallow"),
    "pose-refused-in-cycle": _p("S3", "cycle-dependent", "refuses poses (1001) while a cycle is on", "cycle", True),
    "pose-refused-idle": _p("S3", "cycle-dependent", "refuses poses (1001) while no cycle is on", "cycle", False),
    "connection-limit-20": _p("A1", "connection-count", "stops answering after 20 requests on one connection",
                              "per-connection", 20),
}
#: knobs a random base keeps fixed under these defects (TCP on one port, as the suite's run serves them)
FIXED = {"udp": "off", "stream_port": "same"}
#: ... and per defect: a pose refused in a cycle shows on the stream only when the cycle state is the box's (with a
#: state per connection, no case sends a pose on the connection that holds the cycle: the catalogue sees nothing)
FIXED_FOR = {"pose-refused-in-cycle": {"cycle_scope": "box"}}


def fixed_knobs(defect: str) -> dict[str, str]:
    """The knobs a random base keeps fixed under ``defect``."""
    return FIXED | FIXED_FOR.get(defect, {})


@dataclass
class ConnState:
    """What one connection remembers: the last answer's error code, how many requests were answered."""

    last_error: int = 0
    answered: int = 0


Decide = Callable[..., Any]  # policy.decide's inner function: (choices, event, cycle) -> Reply
Answer = Callable[..., bytes]  # policy.answer: (choices, action, error) -> bytes


def _index_rule(rule: Any, first: int, position: int) -> int:
    if rule == 100:
        return (first + position) % 100
    return (first + position) & int(rule)


def _size_refusal(p: Planted, h: wire.Header, data: bytes, first: int) -> tuple[str, bytes] | None:
    """("refuse"|"close"|"silent", frame) for a request the size rules refuse; ("ok", corrected frame) for an
    index rule met (its indexes made right for the box's other checks); None: no opinion."""
    kind = p.rule[0]
    if h.action not in (POSE, REG, TOL) or h.count == 0:
        return None
    if kind == "count" and h.count >= p.rule[1]:
        return p.rule[2], data
    if kind == "count-of" and h.action in p.rule[2:] and h.count >= p.rule[1]:
        return "error", data
    if kind == "bytes" and len(data) > p.rule[1]:
        return p.rule[2], data
    if kind == "index" and h.length in (5, 25) and len(data) == h.frame_len:
        fixed = bytearray(data)
        for i in range(h.count):
            at = wire.HEADER_LEN + i * h.length
            if data[at] != _index_rule(p.rule[1], first, i):
                return "error", data
            fixed[at] = (first + i) & 0xFF
        return "ok", bytes(fixed)
    return None


def decide(choices: Any, event: Event, cycle: Any, conn: ConnState | None, inner: Decide, answer: Answer) -> Any:
    """The policy's reply to ``event``, with the planted systematic defect applied."""
    p = SYSTEMATIC[choices.defect]
    kind = p.rule[0]
    first = int(choices.first_index)
    if isinstance(event, Frame) and not wire.not_a_request(event.header, choices.has_extension):
        h = event.header
        refusal = _size_refusal(p, h, event.data, first)
        if refusal is not None:
            how, data = refusal
            if how == "close":
                return inner(choices, Close(), cycle)
            if how == "silent":
                return _reply(inner, choices, event, cycle, b"")
            if how == "error":
                return _reply(inner, choices, event, cycle, answer(choices, h.action, _code(h.action)))
            event = Frame(data, h)
    reply = inner(choices, event, cycle)
    if not isinstance(event, Frame) or not reply.data:
        return _after(p, conn, reply, event)
    h = event.header
    action = h.action
    well = wire.request_ok(event.data, h, choices.check) if not wire.not_a_request(h, choices.has_extension) else False
    if conn is not None and kind in ("sticky", "swallow") and conn.last_error and well:
        error, conn.last_error = conn.last_error, 0
        return replace(reply, data=answer(choices, action, error)) if kind == "sticky" else replace(reply, data=b"")
    if conn is not None and kind == "per-connection":
        conn.answered += 1
        if conn.answered > p.rule[1]:
            return replace(reply, data=b"")
    if well and kind == "twice" and action == p.rule[1]:
        return replace(reply, data=reply.data * 2)
    if well and kind == "as" and action == p.rule[1]:
        return replace(reply, data=answer(choices, p.rule[2], _error_of(reply.data)))
    if kind == "all":
        return replace(reply, data=answer(choices, p.rule[1], _error_of(reply.data)))
    if well and kind == "missing" and action == p.rule[1]:
        return replace(reply, data=b"")
    if well and kind == "refuse" and action == p.rule[1]:
        return replace(reply, data=answer(choices, action, p.rule[2]))
    if well and kind == "cycle" and action == POSE and bool(cycle.on) == p.rule[1]:
        return replace(reply, data=answer(choices, action, wire.POSE_ERROR))
    return _after(p, conn, reply, event)


def _after(p: Planted, conn: ConnState | None, reply: Any, event: Event) -> Any:
    """Remember an error answer (sticky/swallow boxes)."""
    if conn is not None and p.rule[0] in ("sticky", "swallow") and len(reply.data) >= wire.HEADER_LEN:
        conn.last_error = _error_of(reply.data)
    return reply


def _reply(inner: Decide, choices: Any, event: Frame, cycle: Any, data: bytes) -> Any:
    reply = inner(choices, Close(), cycle)  # a Reply of the policy's own type (a close), made to carry the data
    return replace(reply, data=data, close=False)


def _code(action: int) -> int:
    return wire.TOL_ERROR if action == TOL else wire.POSE_ERROR


def _error_of(data: bytes) -> int:
    return wire.Header.parse(data).error if len(data) >= wire.HEADER_LEN else 0

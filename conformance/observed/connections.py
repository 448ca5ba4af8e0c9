"""Connections as observed: who opened them, what crossed them, how they ended.

The listener of ``certify-robot`` fills these in as the robot talks to it, and
``analyze`` builds them from a capture; the judgement (:mod:`.session`, :mod:`.stream_timing`,
and each command's own checks) reads them afterwards and never touches a socket. A
connection's bytes live in its :class:`~conformance.harness.transcript.Transcript`
(``local`` is the box; ``remote`` the robot; ``recv`` is what the robot sent);
:class:`Exchange` adds what the box did about each request and when its answer went out.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from ..harness.transcript import Endpoint, Transcript
from ..protocol import Action

#: How a connection ended (ConnRecord.closed_by).
BY_ROBOT, BY_ROBOT_RESET, BY_BOX, BY_SUITE = "robot", "robot-reset", "box", "suite"


@dataclass
class Exchange:
    """One event the box decoded on a connection (a request, a malformed frame or
    garbage) and what it did about it."""

    offset: int  # stream offset of its first byte (TCP), datagram number (UDP)
    t_request: float  # when the chunk that completed it arrived
    action: int | None  # the request's action, when its header is a request header
    reaction: str  # the box's Reaction value
    answer: bytes | None = None  # the answer's bytes (None: silence)
    answer_text: str = ""
    error_code: int | None = None
    value: int | None = None  # the type-03 block value of a 26/27 answer
    t_answer: float | None = None  # when the answer was written (None: never)
    delay_s: float = 0.0  # how long the box held the answer back on purpose (certify-robot's answer latency)


@dataclass
class ConnRecord:
    """One connection from the robot (or one UDP peer)."""

    number: int  # within the session, from 1
    transport: str  # "tcp" | "udp"
    transcript: Transcript
    local: Endpoint
    peer: Endpoint
    t_open: float
    t_close: float | None = None
    closed_by: str | None = None  # BY_ROBOT, BY_ROBOT_RESET, BY_BOX, BY_SUITE
    close_note: str = ""
    actions: list[int] = field(default_factory=list)  # request actions, in order
    exchanges: list[Exchange] = field(default_factory=list)
    pcap: Path | None = None

    @property
    def open(self) -> bool:
        return self.t_close is None

    @property
    def role(self) -> str:
        """``stream`` (poses only), ``command`` (any other request) or ``unknown`` (no request)."""
        if not self.actions:
            return "unknown"
        return "stream" if all(a == Action.POSE for a in self.actions) else "command"

    @property
    def label(self) -> str:
        return f"conn {self.number} ({self.role}, {self.transport} from {self.peer})"


@dataclass
class InjectionEvent:
    name: str
    t: float
    conn: int
    note: str


@dataclass
class SessionRecord:
    number: int  # from 1
    t_start: float
    conns: list[ConnRecord] = field(default_factory=list)
    t_end: float | None = None
    end_reason: str = ""
    last_activity: float = 0.0
    injected: list[InjectionEvent] = field(default_factory=list)
    pcap: Path | None = None  # every connection of the session in one file

    @property
    def tcp(self) -> list[ConnRecord]:
        return [c for c in self.conns if c.transport == "tcp"]

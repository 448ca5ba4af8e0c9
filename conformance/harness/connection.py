"""One way to talk to a box, for the cases, the fuzzer and the diagnose experiments: dial, send, and
receive with a deadline (what boofuzz's ``ITargetConnection`` is to its fuzzers).

:class:`Dialer` holds where and how: the box, the profile, the transcript every byte goes to, the
time_out (the profile's unless given) and, optionally, a deadline that cuts every wait (the diagnose
phase's). :meth:`Dialer.dial` opens a recorded :class:`~.client.TcpConnection`, :meth:`Dialer.udp` a
:class:`~.client.UdpChannel`; both are a :class:`Connection`: ``send``, ``receive(deadline)`` (what the
box did by then, as an :data:`~.outcomes.Outcome`, never an exception), ``request`` and ``close``.
Only a box that cannot be reached raises (:class:`~.target.Unreachable`, from ``dial``).
"""

from __future__ import annotations

import math
import time
from typing import Protocol

from ..protocol import Frame, Profile
from .client import TcpConnection, UdpChannel
from .outcomes import Outcome
from .target import Target
from .transcript import Transcript

__all__ = ["Connection", "Dialer"]


class Connection(Protocol):
    """A recorded connection to a box (TCP or UDP)."""

    conn_id: int
    time_out_s: float

    def send(self, data: bytes | Frame, note: str = "") -> object: ...

    def next_outcome(self, timeout_s: float | None = None, since: float | None = None) -> Outcome: ...

    def receive(self, deadline: float, since: float | None = None) -> Outcome: ...

    def request(self, data: bytes | Frame, note: str = "", timeout_s: float | None = None) -> Outcome: ...


class Dialer:
    """Where and how connections to one box are made (see the module docstring)."""

    def __init__(self, transcript: Transcript, target: Target, profile: Profile, time_out_s: float | None = None,
                 deadline: float | None = None) -> None:
        self.transcript, self.target, self.profile = transcript, target, profile
        #: the bound on connect and every answer: the profile's time_out unless given
        self.time_out_s: float = profile.time_out_s if time_out_s is None else time_out_s
        #: time.monotonic() after which no wait runs on (None: none)
        self.deadline = deadline

    def left(self) -> float:
        """Seconds left before the deadline (infinite without one)."""
        return math.inf if self.deadline is None else self.deadline - time.monotonic()

    def wait_s(self) -> float:
        """The wait for one answer: time_out, cut to what is left before the deadline."""
        return max(0.0, min(self.time_out_s, self.left()))

    def by(self) -> float:
        """The deadline of a wait for one answer starting now."""
        return time.monotonic() + self.wait_s()

    def dial(self, label: str, target: Target | None = None) -> TcpConnection:
        """A new recorded TCP connection, connected (raises :class:`~.target.Unreachable`)."""
        return TcpConnection(self.transcript, target or self.target, self.profile, label, self.wait_s()).connect()

    def udp(self, label: str, target: Target) -> UdpChannel:
        """A recorded UDP channel to ``target`` (raises :class:`~.target.Unreachable`)."""
        return UdpChannel(self.transcript, target, self.profile, label)

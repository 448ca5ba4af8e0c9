"""The exact socket transcript of one case: every connect, byte sent and received, close.

Everything the suite sees on the wire goes through a :class:`Transcript`. Reports
quote it (wire log, hex), and evidence writers subscribe to it as listeners so pcaps
are written *as the case runs* (an interrupted run leaves readable files).
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Protocol

#: Received bytes one case records at most (the first ones: enough for the evidence of a flood).
RECV_BUDGET = 4 << 20


class Kind:
    """What happened on a connection (WireEvent.kind)."""

    CONNECT = "connect"  # TCP handshake completed (or UDP socket bound)
    CONNECT_FAILED = "connect-failed"  # refused / timed out: data holds nothing, note says why
    SEND = "send"  # bytes we wrote (one sendall / one datagram)
    RECV = "recv"  # bytes the peer sent, as one recv returned them (one datagram for UDP)
    CLOSE = "close"  # we closed our side (FIN)
    ABORT = "abort"  # we reset the connection (RST)
    PEER_CLOSE = "peer-close"  # the peer closed its side (FIN: recv returned b"")
    PEER_RESET = "peer-reset"  # the peer reset the connection (RST)
    NOTE = "note"  # a step marker for the reader; no bytes on the wire


@dataclass(frozen=True)
class Endpoint:
    host: str
    port: int

    def __str__(self) -> str:
        return f"[{self.host}]:{self.port}" if ":" in self.host else f"{self.host}:{self.port}"


@dataclass(frozen=True)
class ConnectionInfo:
    conn: int  # id within the transcript, from 1
    transport: str  # "tcp" | "udp"
    local: Endpoint
    remote: Endpoint
    label: str = ""  # e.g. "command", "stream", "liveness"


@dataclass(frozen=True)
class WireEvent:
    t: float  # wall-clock time.time() seconds
    conn: int
    kind: str
    data: bytes = b""
    note: str = ""  # the step, e.g. "CycleOn request", "liveness probe"


class Listener(Protocol):
    def on_connection(self, transcript: Transcript, info: ConnectionInfo) -> None: ...

    def on_event(self, transcript: Transcript, info: ConnectionInfo, event: WireEvent) -> None: ...

    def close(self) -> None: ...


@dataclass
class Transcript:
    """Thread-safe, append-only record of one case's traffic."""

    case_id: str = ""
    connections: dict[int, ConnectionInfo] = field(default_factory=dict)
    events: list[WireEvent] = field(default_factory=list)
    listeners: list[Listener] = field(default_factory=list)
    clock: Callable[[], float] = time.time
    #: how many waits for an answer ran out the full time_out (an unresponsive box)
    timeouts: int = 0
    #: at most this many received bytes are recorded (a flooding box): more are counted, not kept
    recv_budget: int = RECV_BUDGET
    recorded_recv: int = 0
    unrecorded_recv: int = 0
    _lock: threading.Lock = field(default_factory=threading.Lock, repr=False)

    def open(self, transport: str, local: Endpoint, remote: Endpoint, label: str = "") -> ConnectionInfo:
        with self._lock:
            info = ConnectionInfo(len(self.connections) + 1, transport, local, remote, label)
            self.connections[info.conn] = info
            for listener in self.listeners:
                listener.on_connection(self, info)
            return info

    def add(self, conn: int, kind: str, data: bytes = b"", note: str = "") -> WireEvent:
        with self._lock:
            if kind == Kind.RECV and data:
                room = max(0, self.recv_budget - self.recorded_recv)
                if len(data) > room:
                    if not self.unrecorded_recv:
                        self._note_locked(conn, f"the box has sent more than {self.recv_budget} bytes in this case: "
                                                "further bytes are counted, not recorded")
                    self.unrecorded_recv += len(data) - room
                    data = data[:room]
                self.recorded_recv += len(data)
                if not data:
                    return WireEvent(self.clock(), conn, kind, b"", note)
            event = WireEvent(self.clock(), conn, kind, bytes(data), note)
            self.events.append(event)
            info = self.connections.get(conn)
            if info is not None:
                for listener in self.listeners:
                    listener.on_event(self, info, event)
            return event

    def note(self, text: str, conn: int = 0) -> None:
        self.add(conn, Kind.NOTE, note=text)

    def _note_locked(self, conn: int, text: str) -> None:
        event = WireEvent(self.clock(), conn, Kind.NOTE, b"", text)
        self.events.append(event)
        info = self.connections.get(conn)
        if info is not None:
            for listener in self.listeners:
                listener.on_event(self, info, event)

    def close(self) -> None:
        """Close every listener (flushes evidence); the transcript stays readable."""
        with self._lock:
            listeners, self.listeners = self.listeners, []
        for listener in listeners:
            listener.close()

    # -- reading ---------------------------------------------------------------------
    def sent(self, conn: int | None = None) -> bytes:
        return b"".join(e.data for e in self.events if e.kind == Kind.SEND and conn in (None, e.conn))

    def received(self, conn: int | None = None) -> bytes:
        return b"".join(e.data for e in self.events if e.kind == Kind.RECV and conn in (None, e.conn))

    @property
    def started(self) -> float | None:
        return self.events[0].t if self.events else None

"""The suite as an AI Box: an asyncio TCP + UDP server that answers the robot with the
reference box's logic and records every connection (a transcript, a pcapng written as
it happens, the box's decisions; per connection in :mod:`.connection`).

Sessions are told apart from the connections: a connection accepted while no session
is open starts one; a session ends when all its connections are closed (at once, or
``grace_s`` later when all of them were stream connections: the command connection may
still come). Every wait is bounded: ``wait_s`` for the robot to connect and for a
silent session, ``linger_s`` for connections left open after the command connection
closed, ``max_session_s`` for a session. Connections the suite has to close are
recorded as closed by the suite (S5 judges them). After ``sessions`` sessions, or when
a wait runs out, :meth:`CertifyListener.run` returns the :class:`~.records.RunRecord`.
"""

from __future__ import annotations

import asyncio
import contextlib
import traceback
from collections.abc import Callable
from typing import Any

from ..endpoints.behaviour import BoxBehaviour, Decision
from ..endpoints.protocols import format_address, listen, resolve
from ..evidence.pcap import PcapRecorder
from ..harness.transcript import Endpoint, Kind, Transcript
from ..observed.connections import ConnRecord, SessionRecord
from ..protocol import Frame, ProtocolError
from .records import CertifyConfig, RunRecord, monotonic_wall
from .robot_connection import CertifyTcpProtocol, CertifyUdpProtocol, endpoint, exchange_of

TICK_S = 0.05


def _stream_only(session: SessionRecord) -> bool:
    """Only stream connections so far: the command connection may still come (``grace_s``)."""
    return all(c.role == "stream" for c in session.tcp)


class CertifyListener:
    """``await start()``, then ``await run()`` until the sessions are done or a wait runs out."""

    def __init__(self, config: CertifyConfig, on_event: Callable[[str], None] | None = None) -> None:
        self.config = config
        self.on_event = on_event
        self.behaviour = BoxBehaviour(config.box_config())
        self.latency = config.answer_latency()
        self.clock = monotonic_wall()
        self.t_start = self.clock()
        self.sessions: list[SessionRecord] = []
        self.current: SessionRecord | None = None
        self.protocols: dict[int, CertifyTcpProtocol] = {}  # id(ConnRecord) -> protocol
        self.udp_peers: dict[tuple[int, str], ConnRecord] = {}
        self.udp_waiting: list[ConnRecord] = []
        self.errors: list[str] = []
        self.refused = 0
        self.end_reason = ""
        self.end_note = ""
        self.host = config.host
        self.tcp_port = 0
        self.udp_port: int | None = None
        self._server: asyncio.AbstractServer | None = None
        self._udp: asyncio.DatagramTransport | None = None
        self._done: asyncio.Event | None = None
        self._stop_note = ""

    # -- life cycle ---------------------------------------------------------------------------
    async def start(self) -> None:
        loop = asyncio.get_running_loop()
        self._done = asyncio.Event()
        family, self.host = await resolve(loop, self.config.host)
        server, self._udp = await listen(loop, family, self.host, self.config.port, lambda: CertifyTcpProtocol(self),
                                         (lambda: CertifyUdpProtocol(self)) if self.config.udp else None)
        self.tcp_port = server.sockets[0].getsockname()[1]
        if self._udp is not None:
            self.udp_port = self._udp.get_extra_info("sockname")[1]
        self._server = server
        self.t_start = self.clock()

    def describe(self) -> str:
        line = f"listening tcp {format_address(self.host, self.tcp_port)}"
        if self.udp_port is not None:
            line += f" udp {format_address(self.host, self.udp_port)}"
        return line

    def stop(self, note: str = "interrupted") -> None:
        """End the run now (a signal): the session in progress is judged as it stands."""
        self._stop_note = note

    async def run(self) -> RunRecord:
        assert self._done is not None, "start() first"
        while not self._done.is_set():
            with self.guard("watching the sessions"):
                self._tick()
            with contextlib.suppress(asyncio.TimeoutError):
                await asyncio.wait_for(self._done.wait(), TICK_S)
        if self._server is not None:
            self._server.close()
        if self._udp is not None:
            self._udp.close()
        if self.current is not None:
            self._end_session(self.end_note or "the run ended")
        if self.udp_waiting:  # datagrams but never a TCP connection
            self._new_session(self.udp_waiting[0].t_open)
            self._end_session("only UDP datagrams, no TCP connection")
        deadline = asyncio.get_running_loop().time() + 1.0
        while any(p.transport is not None and not p.transport.is_closing() for p in self.protocols.values()):
            if asyncio.get_running_loop().time() > deadline:
                break
            await asyncio.sleep(0.01)
        await asyncio.sleep(0.05)  # let connection_lost callbacks land in the transcripts
        for session in self.sessions:
            for conn in session.conns:
                conn.transcript.close()
        return RunRecord(self.config, self.t_start, self.clock(), self.host, self.tcp_port, self.udp_port,
                         self.sessions, self.end_reason, self.end_note, self.refused, self.errors)

    @contextlib.contextmanager
    def guard(self, what: str):
        """The suite's own failures become an ERROR case, never a traceback on the robot's account."""
        try:
            yield
        except Exception as exc:  # noqa: BLE001 - recorded and reported as ERROR
            tb = traceback.format_exception_only(type(exc), exc)[-1].strip()
            self.errors.append(f"{what}: {tb}")

    def emit(self, text: str) -> None:
        if self.on_event is not None:
            self.on_event(text)

    # -- sessions ----------------------------------------------------------------------------------
    def _new_session(self, now: float) -> SessionRecord:
        session = SessionRecord(len(self.sessions) + 1, now, last_activity=now)
        self.sessions.append(session)
        self.current = session
        for rec in self.udp_waiting:
            rec.number = len(session.conns) + 1
            session.conns.append(rec)
        self.udp_waiting = []
        self.emit(f"session {session.number}: started")
        return session

    def accept(self, proto: CertifyTcpProtocol, transport: asyncio.BaseTransport) -> tuple[SessionRecord, ConnRecord] | None:
        assert self._done is not None
        now = self.clock()
        if self._done.is_set() or (self.current is None and len(self.sessions) >= self.config.sessions):
            self.refused += 1
            return None
        new = self.current is None
        session = self.current or self._new_session(now)
        number = len(session.conns) + 1
        local, peer = endpoint(transport.get_extra_info("sockname")), endpoint(transport.get_extra_info("peername"))
        transcript = Transcript(case_id=f"session-{session.number}/conn-{number}", clock=self.clock)
        rec = ConnRecord(number, "tcp", transcript, local, peer, now)
        if self.config.pcap_dir is not None:
            rec.pcap = self.config.pcap_dir / f"session-{session.number}-conn-{number}.pcapng"
            PcapRecorder.attach(transcript, rec.pcap)
        transcript.open("tcp", local, peer, label="robot connection")
        event = transcript.add(1, Kind.CONNECT, note=f"accepted from robot {peer} (session {session.number}, connection {number})")
        rec.t_open = session.last_activity = event.t  # the connection's time line starts with its CONNECT event
        if new:
            session.t_start = event.t
        session.conns.append(rec)
        self.protocols[id(rec)] = proto
        self.emit(f"session {session.number}: connection {number} accepted from {peer}")
        return session, rec

    def activity(self, session: SessionRecord | None) -> None:
        if session is not None:
            session.last_activity = self.clock()

    def closed(self, session: SessionRecord | None, rec: ConnRecord) -> None:
        if session is None:
            return
        session.last_activity = self.clock()
        self.emit(f"session {session.number}: connection {rec.number} ({rec.role}) closed by {rec.closed_by}")
        if session is self.current:
            self._check_current()

    def _check_current(self) -> None:
        session = self.current
        if session is None or not session.tcp or any(c.open for c in session.tcp):
            return
        if not _stream_only(session):
            self._end_session("all connections closed")

    def _tick(self) -> None:
        assert self._done is not None
        now, cfg = self.clock(), self.config
        if self._stop_note:
            self._finish("interrupted", self._stop_note)
            return
        session = self.current
        if session is None:
            since = (self.sessions[-1].t_end or now) if self.sessions else self.t_start
            if now - since >= cfg.wait_s:
                if self.sessions:
                    self._finish("wait", f"session {len(self.sessions) + 1} did not start within --wait {cfg.wait_s:g} s")
                else:
                    self._finish("wait", f"no robot connected within --wait {cfg.wait_s:g} s")
            return
        tcp = session.tcp
        open_ = [c for c in tcp if c.open]
        if tcp and not open_:
            last = max(c.t_close or now for c in tcp)
            if not _stream_only(session) or now - last >= cfg.grace_s:
                self._end_session("all connections closed")
            return
        cmd_closed = [c.t_close for c in tcp if c.role == "command" and c.t_close is not None]
        if cmd_closed and open_ and now - min(cmd_closed) >= cfg.linger_s:
            self._end_session(f"left open {cfg.linger_s:g} s (--linger) after the command connection closed")
        elif now - session.last_activity >= cfg.wait_s:
            self._end_session(f"nothing happened for --wait {cfg.wait_s:g} s")
        elif now - session.t_start >= cfg.max_session_s:
            self._end_session(f"the session reached --max-session {cfg.max_session_s:g} s")

    def _end_session(self, reason: str) -> None:
        session = self.current
        if session is None:
            return
        self.current = None
        for conn in session.tcp:
            if conn.open:
                proto = self.protocols.get(id(conn))
                if proto is not None:
                    proto.force_close(f"closed by the suite: {reason}")
        session.t_end, session.end_reason = self.clock(), reason
        self.emit(f"session {session.number}: ended ({reason})")
        if len(self.sessions) >= self.config.sessions:
            self._finish("complete", f"{len(self.sessions)} session(s) complete")

    def _finish(self, reason: str, note: str) -> None:
        assert self._done is not None
        if not self._done.is_set():
            self.end_reason, self.end_note = reason, note
            self._done.set()

    # -- UDP ---------------------------------------------------------------------------------------
    def datagram(self, data: bytes, addr: Any, transport: asyncio.DatagramTransport | None) -> None:
        now = self.clock()
        peer = endpoint(addr)
        session = self.current
        key = (session.number if session else 0, str(peer))
        rec = self.udp_peers.get(key)
        if rec is None:
            owner = session.conns if session else self.udp_waiting
            number = len(owner) + 1
            transcript = Transcript(case_id=f"udp-{peer}", clock=self.clock)
            local = Endpoint(self.host, self.udp_port or 0)
            rec = ConnRecord(number, "udp", transcript, local, peer, now)
            if self.config.pcap_dir is not None:
                rec.pcap = self.config.pcap_dir / f"udp-{len(self.udp_peers) + 1}.pcapng"
                PcapRecorder.attach(transcript, rec.pcap)
            transcript.open("udp", local, peer, label="robot datagrams")
            transcript.add(1, Kind.CONNECT, note=f"datagrams from robot {peer}")
            owner.append(rec)
            self.udp_peers[key] = rec
        self.activity(session)
        t = rec.transcript.add(1, Kind.RECV, data).t
        decisions: list[tuple[Frame | ProtocolError, Decision]] = []
        out = self.behaviour.receive_datagram(data, lambda raw, event, decision: decisions.append((event, decision)))
        for event, decision in decisions:
            action = event.action if isinstance(event, Frame) else self.behaviour.request_action(event)
            if action is not None:
                rec.actions.append(int(action))
            exchange = exchange_of(len(rec.exchanges), t, None if action is None else int(action), decision)
            exchange.answer = decision.udp
            rec.exchanges.append(exchange)
            if out is not None and transport is not None and not transport.is_closing():
                transport.sendto(out, addr)
                exchange.t_answer = rec.transcript.add(1, Kind.SEND, out).t

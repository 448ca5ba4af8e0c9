"""One robot connection as the suite sees it: an asyncio protocol that records the bytes
in the connection's transcript, answers through the reference box's
:class:`~conformance.endpoints.box_connection.BoxConnection` (its trace says what the box
decided for each request, which becomes an :class:`~.records.Exchange`), holds answers
back (``--inject slow``), closes mid-cycle (``--inject close-mid-cycle``) and records who
closed the connection. Session bookkeeping is the listener's (:mod:`.listener`); this
module knows it only as a :class:`Listener` (what a connection asks of it), so the
listener imports the connections and not the other way round.
"""

from __future__ import annotations

import asyncio
from collections import deque
from collections.abc import Callable
from contextlib import AbstractContextManager
from typing import Any, Protocol, cast

from ..endpoints.behaviour import BoxBehaviour, Decision, Reaction
from ..endpoints.box_connection import BoxConnection
from ..harness.transcript import Endpoint, Kind
from ..observed.connections import (
    BY_BOX,
    BY_ROBOT,
    BY_ROBOT_RESET,
    BY_SUITE,
    ConnRecord,
    Exchange,
    InjectionEvent,
    SessionRecord,
)
from ..protocol import Action, Frame, ProtocolError, action_name
from ..protocol.frames import ValueBlock
from .latency import AnswerLatency
from .records import CertifyConfig


class Listener(Protocol):
    """What a connection asks of the listener that accepted it (:class:`~.listener.CertifyListener`)."""

    @property
    def config(self) -> CertifyConfig: ...

    @property
    def behaviour(self) -> BoxBehaviour: ...

    @property
    def clock(self) -> Callable[[], float]: ...

    @property
    def latency(self) -> AnswerLatency:
        """The run's answer latencies (CycleOn, CycleOff, 27: a real box takes time)."""
        ...

    def guard(self, what: str) -> AbstractContextManager[Any]:
        """Turns the suite's own failures inside the block into an ERROR of the run."""
        ...

    def accept(self, proto: CertifyTcpProtocol, transport: asyncio.BaseTransport) -> tuple[SessionRecord, ConnRecord] | None:
        """The connection's session and record, or None: refused."""
        ...

    def activity(self, session: SessionRecord | None) -> None: ...

    def closed(self, session: SessionRecord | None, rec: ConnRecord) -> None: ...

    def datagram(self, data: bytes, addr: Any, transport: asyncio.DatagramTransport | None) -> None: ...


def endpoint(address: object) -> Endpoint:
    if isinstance(address, tuple) and len(address) >= 2:
        return Endpoint(str(address[0]), int(address[1]))
    return Endpoint(str(address), 0)


class CertifyTcpProtocol(asyncio.Protocol):
    """One robot connection: record, answer through the box logic, inject."""

    def __init__(self, listener: Listener) -> None:
        self.listener = listener
        self.transport: asyncio.Transport | None = None
        self.rec: ConnRecord | None = None
        self.session: SessionRecord | None = None
        self.box: BoxConnection | None = None
        self.offset = 0
        self.t_chunk = 0.0
        self.pending: list[Exchange] = []
        self.close_after = ""
        self.queue: deque[tuple[float, bytes, list[Exchange], str]] = deque()
        self.timer: asyncio.TimerHandle | None = None

    # -- asyncio callbacks -----------------------------------------------------------------
    def connection_made(self, transport: asyncio.BaseTransport) -> None:
        tcp = self.transport = cast(asyncio.Transport, transport)  # a stream server's transport
        with self.listener.guard("accepting a connection"):
            accepted = self.listener.accept(self, transport)
            if accepted is not None:
                self.session, self.rec = accepted
                self.box = BoxConnection(self.listener.behaviour, self._trace)
                return
        tcp.abort()

    def data_received(self, data: bytes) -> None:
        rec, box = self.rec, self.box
        if rec is None or box is None or rec.t_close is not None:
            return
        with self.listener.guard(f"handling bytes on {rec.label}"):
            self.t_chunk = rec.transcript.add(1, Kind.RECV, data).t
            self.listener.activity(self.session)
            out = box.receive_data(data)
            exchanges, self.pending = self.pending, []
            close = self.close_after or (box.close_reason if box.should_close else "")
            self.close_after = ""
            if out or close:
                self._send(out, exchanges, close)

    def eof_received(self) -> bool:
        rec = self.rec
        if rec is not None and rec.t_close is None:
            rec.transcript.add(1, Kind.PEER_CLOSE, note="the robot closed its side (FIN)")
            dropped = sum(len(item[2]) for item in self.queue)
            self._close(BY_ROBOT, "the box closes its side after the robot's FIN"
                        + (f"; {dropped} held-back answer(s) dropped" if dropped else ""))
        return True

    def connection_lost(self, exc: Exception | None) -> None:
        if self.timer is not None:
            self.timer.cancel()
            self.timer = None
        rec = self.rec
        if rec is None or rec.t_close is not None:
            return
        if exc is None:
            rec.transcript.add(1, Kind.PEER_CLOSE, note="connection lost")
            self._record_close(BY_ROBOT, "connection lost")
        else:
            rec.transcript.add(1, Kind.PEER_RESET, note=f"the robot reset the connection ({exc})")
            self._record_close(BY_ROBOT_RESET, f"reset: {exc}")

    # -- the box's decisions ----------------------------------------------------------------
    def _trace(self, raw: bytes, event: Frame | ProtocolError, decision: Decision) -> None:
        rec, session, listener = self.rec, self.session, self.listener
        assert rec is not None and session is not None
        offset = self.offset
        self.offset += len(raw)
        if isinstance(event, Frame):
            action: int | None = int(event.action)
        else:
            found = listener.behaviour.request_action(event)
            action = None if found is None else int(found)
        if action is not None:
            rec.actions.append(action)
        exchange = exchange_of(offset, self.t_chunk, action, decision)
        rec.exchanges.append(exchange)
        if decision.tcp is not None:
            exchange.delay_s = listener.config.slow_delay_s or listener.latency.delay_s(action)
            self.pending.append(exchange)
        if (
            "close-mid-cycle" in listener.config.inject
            and isinstance(event, Frame) and event.action is Action.CYCLE_ON
            and decision.reaction is Reaction.OK and not any(i.name == "close-mid-cycle" for i in session.injected)
        ):
            note = "inject close-mid-cycle: the box closes the command connection after answering CycleOn"
            session.injected.append(InjectionEvent("close-mid-cycle", self.t_chunk, rec.number, note))
            self.close_after = note

    # -- writing, holding back, closing --------------------------------------------------------
    def _send(self, out: bytes, exchanges: list[Exchange], close: str) -> None:
        """Write the answers now, or each ``delay_s`` after its request (in order: never before the one before)."""
        if not self.queue and not any(e.delay_s for e in exchanges):
            self._write(out, exchanges, close)
            return
        loop = asyncio.get_running_loop()
        now = loop.time()
        last = self.queue[-1][0] if self.queue else now
        if exchanges and b"".join(e.answer or b"" for e in exchanges) == out:
            for i, ex in enumerate(exchanges):
                last = max(now + ex.delay_s, last)
                self.queue.append((last, ex.answer or b"", [ex], close if i == len(exchanges) - 1 else ""))
        else:  # a close without an answer (or bytes the exchanges do not account for): after what is held
            last = max(now + max((e.delay_s for e in exchanges), default=0.0), last)
            self.queue.append((last, out, exchanges, close))
        if self.timer is None:
            self.timer = loop.call_at(self.queue[0][0], self._release)

    def _release(self) -> None:
        self.timer = None
        with self.listener.guard("sending held-back answers"):
            loop = asyncio.get_running_loop()
            out, exchanges, close = bytearray(), [], ""
            while self.queue and self.queue[0][0] <= loop.time():
                _, data, held, closing = self.queue.popleft()
                out += data
                exchanges += held
                close = close or closing
            if out or close:
                self._write(bytes(out), exchanges, close)
            if self.queue:
                self.timer = loop.call_at(self.queue[0][0], self._release)

    def _write(self, out: bytes, exchanges: list[Exchange], close: str) -> None:
        rec, transport = self.rec, self.transport
        if rec is None or transport is None or rec.t_close is not None or transport.is_closing():
            return
        if out:
            transport.write(out)
            t = rec.transcript.add(1, Kind.SEND, out, note=held_note(exchanges, self.listener.config.slow_delay_s)).t
            for exchange in exchanges:
                exchange.t_answer = t
        if close:
            self._close(BY_BOX, close)

    def _close(self, by: str, note: str) -> None:
        """Close our side (FIN) and record who ended the connection."""
        rec, transport = self.rec, self.transport
        self.queue.clear()
        if rec is None or rec.t_close is not None:
            return
        self._record_close(by, note)
        rec.transcript.add(1, Kind.CLOSE, note=note)
        if transport is not None and not transport.is_closing():
            transport.close()

    def _record_close(self, by: str, note: str) -> None:
        rec = self.rec
        assert rec is not None
        rec.t_close, rec.closed_by, rec.close_note = self.listener.clock(), by, note
        self.listener.closed(self.session, rec)

    def force_close(self, note: str) -> None:
        """The suite ends a connection the robot left open (S5 judges it)."""
        self._close(BY_SUITE, note)


def held_note(exchanges: list[Exchange], slow_s: float) -> str:
    """The wire log's note on an answer held back: ``--inject slow``, or the box's latency (ms) per answer."""
    if slow_s:
        return "slow: held back"
    held = [f"{action_name(e.action) if e.action is not None else '?'} after {e.delay_s * 1000:.0f} ms"
            for e in exchanges if e.delay_s]
    return f"answer latency: {', '.join(held)}" if held else ""


def exchange_of(offset: int, t: float, action: int | None, decision: Decision) -> Exchange:
    frame = decision.frame
    value = None
    if frame is not None and frame.blocks and isinstance(frame.blocks[0], ValueBlock):
        value = frame.blocks[0].value
    return Exchange(offset, t, action, decision.reaction.value, decision.tcp, frame.describe() if frame else "",
                    frame.error_code if frame else None, value)


class CertifyUdpProtocol(asyncio.DatagramProtocol):
    def __init__(self, listener: Listener) -> None:
        self.listener = listener
        self.transport: asyncio.DatagramTransport | None = None

    def connection_made(self, transport: asyncio.BaseTransport) -> None:
        self.transport = cast(asyncio.DatagramTransport, transport)  # a datagram endpoint's transport

    def datagram_received(self, data: bytes, addr: Any) -> None:
        with self.listener.guard("handling a UDP datagram"):
            self.listener.datagram(data, addr, self.transport)

    def error_received(self, exc: Exception) -> None:
        pass

"""The reference box's connections on asyncio: one protocol per TCP connection, the UDP endpoint, and
:class:`ConnectionTable`, which admits, evicts and sweeps them (:class:`~.server.ReferenceBox` builds on it).

The hot path is one pose in, one cached answer out:

* ``asyncio.BufferedProtocol`` per connection, reading into one shared buffer;
  everything one read completes is answered with one ``transport.write``.
* Bounded: a connection holds at most one partial frame (the decoder never waits
  for more than 6389 bytes); at most ``max_connections`` connections, a new one
  past the limit evicts the connection that has gone longest without an answer if
  that is at least ``evict_after`` seconds ago, else it is refused; connections
  that send nothing for ``idle_timeout`` seconds are closed; a connection whose
  answers pile up unread (write buffer above 64 KiB) is not read until they drain.
* ``latency_ms`` delays answers per connection in order (one timer per connection).
"""

from __future__ import annotations

import asyncio
import socket
from collections import deque
from collections.abc import Callable
from typing import Any, cast

from ..harness.target import Target
from ..protocol import Frame, ProtocolError
from .behaviour import BoxBehaviour, Decision
from .box_connection import BoxConnection
from .framelog import FrameLog

DEFAULT_MAX_CONNECTIONS = 2000
DEFAULT_IDLE_TIMEOUT = 300.0
#: pause reading a connection whose unsent answers exceed this (back-pressure)
WRITE_HIGH = 64 * 1024
WRITE_LOW = 16 * 1024
#: answers held back by ``latency_ms`` above which a connection stops being read
DELAY_HIGH = 256 * 1024
#: a UDP answer is dropped when the socket's send buffer backlog exceeds this
UDP_BUFFER_LIMIT = 1 << 20


def format_address(host: str, port: int) -> str:
    """``host:port``, or ``[host]:port`` for an IPv6 address."""
    return str(Target(host, port))


async def resolve(loop: asyncio.AbstractEventLoop, host: str) -> tuple[int, str]:
    """(family, address): one local address for ``host``, so that port 0 means one port for TCP and UDP."""
    infos = await loop.getaddrinfo(host, None, type=socket.SOCK_STREAM, flags=socket.AI_PASSIVE)
    if not infos:
        raise OSError(f"cannot resolve {host!r}")
    family, _, _, _, sockaddr = infos[0]
    return int(family), str(sockaddr[0])


async def listen(loop: asyncio.AbstractEventLoop, family: int, host: str, port: int,
                 tcp: Callable[[], asyncio.BaseProtocol], udp: Callable[[], asyncio.BaseProtocol] | None = None,
                 udp_port: int | None = None, backlog: int = 100,
                 ) -> tuple[asyncio.Server, asyncio.DatagramTransport | None]:
    """A TCP server on ``host:port`` and, with a ``udp`` protocol factory, a UDP endpoint on the
    same port (or on ``udp_port``). With port 0 and one port for both, up to 20 tries for a port
    that is free for UDP too; an OSError names what could not be bound."""
    attempts = 20 if port == 0 and udp is not None and udp_port is None else 1
    for attempt in range(attempts):
        server = await loop.create_server(tcp, host, port, family=family, reuse_address=True, backlog=backlog)
        if udp is None:
            return server, None
        local = (host, server.sockets[0].getsockname()[1] if udp_port is None else udp_port)
        try:
            transport, _ = await loop.create_datagram_endpoint(udp, local_addr=local, family=family)
        except OSError as exc:
            server.close()
            await server.wait_closed()
            if attempt + 1 < attempts:
                continue
            raise OSError(exc.errno, f"cannot bind UDP {format_address(*local)}: {exc.strerror}") from None
        return server, transport
    raise AssertionError("unreachable: the last attempt returns or raises")


#: One receive buffer for every connection: the loop is single-threaded and each read
#: is consumed before the next, so connections need no buffer of their own. (A
#: ``Protocol`` would get a fresh 256 KiB bytes object per read, which glibc serves
#: with mmap/munmap: ~10 µs per read, the box's largest cost under load.)
_READ_SIZE = 256 * 1024


class BoxTcpProtocol(asyncio.BufferedProtocol):
    """One robot connection (command or stream: the box does not care which)."""

    __slots__ = (
        "box", "id", "transport", "conn", "receive", "rx", "ans", "rx_seen", "ans_seen", "last_rx",
        "last_progress", "delay", "queue", "queued", "timer", "write_paused", "read_paused", "peer", "closed",
        "close_logged", "buffer", "view", "eof", "write",
    )

    def __init__(self, box: ConnectionTable) -> None:
        self.box = box
        self.id = 0
        self.transport: asyncio.Transport | None = None
        self.rx = self.ans = self.rx_seen = self.ans_seen = 0
        self.last_rx = self.last_progress = 0.0
        self.delay = box.behaviour.config.latency_ms / 1000.0
        self.queue: deque[tuple[float, bytes]] = deque()
        self.queued = 0
        self.timer: asyncio.TimerHandle | None = None
        self.write_paused = self.read_paused = self.closed = self.close_logged = self.eof = False
        self.peer = ""
        self.buffer, self.view = box._read_buffer, box._read_view

    # -- asyncio callbacks ----------------------------------------------------------------
    def connection_made(self, transport: asyncio.BaseTransport) -> None:
        tcp = self.transport = cast(asyncio.Transport, transport)  # a stream server's transport
        self.write = tcp.write
        box = self.box
        if not box._admit(self):
            tcp.abort()
            return
        peer = transport.get_extra_info("peername")
        self.peer = format_address(peer[0], peer[1]) if isinstance(peer, tuple) else str(peer)
        log = box.log
        trace = None
        if log is not None:
            cid, peer_text = self.id, self.peer

            def trace(raw: bytes, event: Frame | ProtocolError, decision: Decision) -> None:
                log.frame(cid, "tcp", peer_text, raw, event, decision)

            log.write({"conn": cid, "transport": "tcp", "peer": peer_text, "direction": "open"})
        self.conn = BoxConnection(box.behaviour, trace)
        self.receive = self.conn.receive_data
        tcp.set_write_buffer_limits(high=WRITE_HIGH, low=WRITE_LOW)

    def get_buffer(self, sizehint: int) -> memoryview:
        return self.view

    def buffer_updated(self, nbytes: int) -> None:  # the hot path
        self.rx += 1
        out = self.receive(self.view[:nbytes].tobytes())
        if out:
            self.ans += 1
            if self.delay:
                self._hold(out)
            else:
                self.write(out)
        if self.conn.should_close:
            self._close(self.conn.close_reason)

    def eof_received(self) -> bool:
        # S5: close our side too, after the answers already written; answers still held
        # back by --latency-ms are sent first (A1), then _release closes
        if self.queue:
            self.eof = True
            return True  # keep the transport half-open until the queue drains
        return False

    def connection_lost(self, exc: Exception | None) -> None:
        self.closed = True
        if self.timer is not None:
            self.timer.cancel()
        self.box._forget(self, "peer closed" if exc is None else f"lost: {exc}")

    def pause_writing(self) -> None:
        self.write_paused = True
        self._update_reading()

    def resume_writing(self) -> None:
        self.write_paused = False
        self._update_reading()

    # -- helpers ----------------------------------------------------------------------------
    def _update_reading(self) -> None:
        want_paused = self.write_paused or self.queued > DELAY_HIGH
        transport = self.transport
        if transport is None or self.closed or transport.is_closing() or want_paused == self.read_paused:
            return
        self.read_paused = want_paused
        if want_paused:
            transport.pause_reading()
        else:
            transport.resume_reading()

    def _hold(self, out: bytes) -> None:
        loop = self.box.loop
        due = loop.time() + self.delay
        self.queue.append((due, out))
        self.queued += len(out)
        if self.timer is None:
            self.timer = loop.call_at(due, self._release)
        if self.queued > DELAY_HIGH:
            self._update_reading()

    def _release(self) -> None:
        self.timer = None
        if self.closed:
            return
        now = self.box.loop.time()
        queue = self.queue
        chunks = []
        while queue and queue[0][0] <= now:
            chunks.append(queue.popleft()[1])
        if chunks:
            data = b"".join(chunks)
            self.queued -= len(data)
            self.write(data)
        if queue:
            self.timer = self.box.loop.call_at(queue[0][0], self._release)
        elif self.eof:
            self._close("peer closed its side; held answers sent")
            return
        self._update_reading()

    def _close(self, reason: str, abort: bool = False) -> None:
        transport = self.transport
        if transport is None or transport.is_closing():
            return
        self.box._log_close(self, reason)
        if abort:
            transport.abort()
        else:
            transport.close()


class BoxUdpProtocol(asyncio.DatagramProtocol):
    def __init__(self, box: ConnectionTable) -> None:
        self.box = box
        self.transport: asyncio.DatagramTransport | None = None
        self.buffered: Callable[[], int] = lambda: 0
        self.delay = box.behaviour.config.latency_ms / 1000.0

    def connection_made(self, transport: asyncio.BaseTransport) -> None:
        self.transport = cast(asyncio.DatagramTransport, transport)  # a datagram endpoint's transport
        # asyncio's datagram transports buffer writes too (typeshed does not declare the method)
        self.buffered = getattr(transport, "get_write_buffer_size", lambda: 0)

    def datagram_received(self, data: bytes, addr: Any) -> None:
        box = self.box
        trace = None
        if box.log is not None:
            log = box.log
            peer = format_address(addr[0], addr[1]) if isinstance(addr, tuple) else str(addr)

            def trace(raw: bytes, event: Frame | ProtocolError, decision: Decision) -> None:
                log.frame("udp", "udp", peer, raw, event, decision)

        out = box.behaviour.receive_datagram(data, trace)
        transport = self.transport
        if out is None or transport is None or transport.is_closing():
            return
        if self.buffered() > UDP_BUFFER_LIMIT:
            box.udp_dropped_answers += 1
            return
        if self.delay:
            box.loop.call_later(self.delay, self._send, out, addr)
        else:
            transport.sendto(out, addr)

    def _send(self, out: bytes, addr: Any) -> None:
        if self.transport is not None and not self.transport.is_closing():
            self.transport.sendto(out, addr)

    def error_received(self, exc: Exception) -> None:  # e.g. ICMP port unreachable from a gone robot
        pass


class ConnectionTable:
    """The box's live TCP connections and their counters: admission (R5's limit, eviction of the
    connection that has gone longest without an answer), close logging and the idle sweep."""

    #: the loop the box runs on (set when it starts)
    loop: asyncio.AbstractEventLoop

    def __init__(self, behaviour: BoxBehaviour, max_connections: int, idle_timeout: float, evict_after: float) -> None:
        self.behaviour = behaviour
        self.max_connections = max_connections
        self.idle_timeout = idle_timeout
        self.evict_after = evict_after
        self.log: FrameLog | None = None
        self.connections: dict[int, BoxTcpProtocol] = {}
        self.accepted = self.refused = self.evicted = self.idle_closed = 0
        self.peak_connections = 0
        self.udp_dropped_answers = 0
        self._next_id = 1
        self._read_buffer = bytearray(_READ_SIZE)
        self._read_view = memoryview(self._read_buffer)
        self._closing = False

    # -- connection bookkeeping ---------------------------------------------------------------
    def _admit(self, conn: BoxTcpProtocol) -> bool:
        if self._closing:
            return False
        if len(self.connections) >= self.max_connections:
            victim = self._victim()
            if victim is None:
                self.refused += 1
                if self.log is not None:
                    self.log.write({"conn": None, "transport": "tcp", "direction": "refused",
                                    "note": f"R5: connection limit {self.max_connections} reached"})
                return False
            self.evicted += 1
            victim._close(f"R5: evicted for a new connection (limit {self.max_connections})", abort=True)
            self.connections.pop(victim.id, None)
        conn.id = self._next_id
        self._next_id += 1
        now = self.loop.time()
        conn.last_rx = conn.last_progress = now
        self.connections[conn.id] = conn
        self.accepted += 1
        self.peak_connections = max(self.peak_connections, len(self.connections))
        return True

    def _victim(self) -> BoxTcpProtocol | None:
        """The connection that has gone longest without an answer, if long enough."""
        now = self.loop.time()
        best, best_key = None, None
        for conn in self.connections.values():
            progress = now if conn.ans != conn.ans_seen else conn.last_progress
            key = (progress, conn.ans, conn.id)
            if best_key is None or key < best_key:
                best, best_key = conn, key
        if best is None or best_key is None or now - best_key[0] < self.evict_after:
            return None
        return best

    def _forget(self, conn: BoxTcpProtocol, reason: str) -> None:
        if conn.id and self.connections.get(conn.id) is conn:
            del self.connections[conn.id]
        if conn.id:
            self._log_close(conn, reason)

    def _log_close(self, conn: BoxTcpProtocol, reason: str) -> None:
        if self.log is not None and not conn.close_logged:
            conn.close_logged = True
            self.log.write({"conn": conn.id, "transport": "tcp", "peer": conn.peer, "direction": "close", "reason": reason})

    async def _sweep(self) -> None:
        """Idle time-outs and progress tracking, from counters (nothing on the hot path)."""
        period = 1.0 if not self.idle_timeout else min(1.0, max(0.05, self.idle_timeout / 4))
        while True:
            await asyncio.sleep(period)
            now = self.loop.time()
            idle = []
            for conn in self.connections.values():
                if conn.rx != conn.rx_seen:
                    conn.rx_seen, conn.last_rx = conn.rx, now
                if conn.ans != conn.ans_seen:
                    conn.ans_seen, conn.last_progress = conn.ans, now
                if self.idle_timeout and now - conn.last_rx >= self.idle_timeout:
                    idle.append(conn)
            for conn in idle:
                self.idle_closed += 1
                conn._close(f"R5: idle for {self.idle_timeout:g} s", abort=True)
                self.connections.pop(conn.id, None)
            if self.log is not None:
                self.log.flush()


__all__ = [
    "DEFAULT_IDLE_TIMEOUT", "DEFAULT_MAX_CONNECTIONS", "ConnectionTable", "BoxTcpProtocol", "BoxUdpProtocol", "format_address",
]

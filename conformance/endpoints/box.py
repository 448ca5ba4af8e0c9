"""The reference AI Box: asyncio TCP and UDP server around :mod:`.behaviour`.

``isight-conformance serve`` runs it; tests and the suite embed it with
:class:`ReferenceBox` (async) or :class:`BoxThread` (a box on its own thread and
loop, for synchronous code)::

    async with ReferenceBox(BoxConfig(), host="127.0.0.1", port=0) as box:
        ...  # box.tcp_port, box.udp_port

    with BoxThread(BoxConfig(not_ready=True)) as box:
        host, port = box.address

Design (the box's hot path is one pose in, one cached answer out):

* ``asyncio.BufferedProtocol`` per connection, reading into one shared buffer;
  everything one read completes is answered with one ``transport.write``.
* Bounded: a connection holds at most one partial frame (the decoder never waits
  for more than 6389 bytes); at most ``max_connections`` connections, a new one
  past the limit evicts the connection that has gone longest without an answer if
  that is at least ``evict_after`` seconds ago, else it is refused; connections
  that send nothing for ``idle_timeout`` seconds are closed; a connection whose
  answers pile up unread (write buffer above 64 KiB) is not read until they drain.
* ``latency_ms`` delays answers per connection in order (one timer per connection).
* ``log``: JSON lines, one per connection event and per frame in and out.
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import signal
import socket
import sys
import threading
import time
from collections import deque
from collections.abc import Callable
from pathlib import Path
from typing import IO, Any

from ..protocol import DEFAULT_PORT, Frame, ProtocolError, Transport
from .behaviour import BoxBehaviour, BoxConfig, BoxConnection, Decision

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
    return f"[{host}]:{port}" if ":" in host else f"{host}:{port}"


class FrameLog:
    """``--log FILE``: one JSON object per line for every frame in and out.

    Keys: ``t`` (Unix time), ``conn`` (connection id, ``"udp"`` for datagrams),
    ``transport``, ``peer``, ``direction`` (``open``/``in``/``out``/``close``/``refused``), ``hex``,
    ``frame`` (decoded summary) or ``error`` (``clause``, ``message``, ``offset``),
    and ``decision``/``note`` for what the box did.
    """

    def __init__(self, target: str | Path | IO[str]) -> None:
        if isinstance(target, (str, Path)):
            self._fh: IO[str] = open(target, "a", encoding="utf-8", buffering=1 << 16)  # noqa: SIM115
            self._owned = True
        else:
            self._fh, self._owned = target, False
        self.records = 0

    def write(self, record: dict[str, Any]) -> None:
        record = {"t": round(time.time(), 6), **record}
        self._fh.write(json.dumps(record, ensure_ascii=False, separators=(",", ":")) + "\n")
        self.records += 1

    def frame(
        self, conn: int | str, transport: str, peer: str, raw: bytes, event: Frame | ProtocolError, decision: Decision
    ) -> None:
        record: dict[str, Any] = {"conn": conn, "transport": transport, "peer": peer, "direction": "in", "hex": raw.hex()}
        if isinstance(event, ProtocolError):
            record["error"] = {"clause": event.clause, "message": event.message, "offset": event.offset}
        else:
            record["frame"] = event.describe()
        record["decision"] = decision.reaction.value
        if decision.note:
            record["note"] = decision.note
        self.write(record)
        data = decision.tcp if transport == "tcp" else decision.udp
        if data is not None and decision.frame is not None:
            self.write({"conn": conn, "transport": transport, "peer": peer, "direction": "out", "hex": data.hex(),
                        "frame": decision.frame.describe()})

    def flush(self) -> None:
        with contextlib.suppress(ValueError, OSError):
            self._fh.flush()

    def close(self) -> None:
        self.flush()
        if self._owned:
            with contextlib.suppress(OSError):
                self._fh.close()


#: One receive buffer for every connection: the loop is single-threaded and each read
#: is consumed before the next, so connections need no buffer of their own. (A
#: ``Protocol`` would get a fresh 256 KiB bytes object per read, which glibc serves
#: with mmap/munmap: ~10 µs per read, the box's largest cost under load.)
_READ_SIZE = 256 * 1024


class _TcpConnection(asyncio.BufferedProtocol):
    """One robot connection (command or stream: the box does not care which)."""

    __slots__ = (
        "box", "id", "transport", "conn", "receive", "rx", "ans", "rx_seen", "ans_seen", "last_rx",
        "last_progress", "delay", "queue", "queued", "timer", "write_paused", "read_paused", "peer", "closed",
        "close_logged", "buffer", "view", "eof",
    )

    def __init__(self, box: ReferenceBox) -> None:
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
        self.transport = transport  # type: ignore[assignment]
        box = self.box
        if not box._admit(self):
            transport.abort()  # type: ignore[attr-defined]
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
        transport.set_write_buffer_limits(high=WRITE_HIGH, low=WRITE_LOW)  # type: ignore[attr-defined]

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
                self.transport.write(out)  # type: ignore[union-attr]
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
            self.transport.write(data)  # type: ignore[union-attr]
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


class _UdpEndpoint(asyncio.DatagramProtocol):
    def __init__(self, box: ReferenceBox) -> None:
        self.box = box
        self.transport: asyncio.DatagramTransport | None = None
        self.delay = box.behaviour.config.latency_ms / 1000.0

    def connection_made(self, transport: asyncio.BaseTransport) -> None:
        self.transport = transport  # type: ignore[assignment]

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
        if transport.get_write_buffer_size() > UDP_BUFFER_LIMIT:  # type: ignore[attr-defined]
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


class ReferenceBox:
    """The reference AI Box on an asyncio loop (TCP and, by default, UDP on the same port)."""

    def __init__(
        self,
        config: BoxConfig | None = None,
        *,
        host: str = "127.0.0.1",
        port: int = DEFAULT_PORT,
        udp: bool = True,
        udp_port: int | None = None,
        max_connections: int = DEFAULT_MAX_CONNECTIONS,
        idle_timeout: float = DEFAULT_IDLE_TIMEOUT,
        evict_after: float = 1.0,
        log: str | Path | IO[str] | FrameLog | None = None,
        behaviour: BoxBehaviour | None = None,
    ) -> None:
        if max_connections < 1:
            raise ValueError("max connections must be at least 1")
        if idle_timeout < 0:
            raise ValueError("idle timeout must be >= 0 (0 = off)")
        if not 0 <= port <= 65535 or (udp_port is not None and not 0 <= udp_port <= 65535):
            raise ValueError("ports must be 0..65535")
        self.behaviour = behaviour or BoxBehaviour(config or BoxConfig())
        self.config = self.behaviour.config
        self.host = host
        self.port = port
        self.udp = udp
        self.udp_port_request = udp_port
        self.max_connections = max_connections
        self.idle_timeout = idle_timeout
        self.evict_after = evict_after
        self._log_target = log
        self.log: FrameLog | None = None
        self.tcp_port: int | None = None
        self.udp_port: int | None = None
        self.bound_host = host
        self.connections: dict[int, _TcpConnection] = {}
        self.accepted = self.refused = self.evicted = self.idle_closed = 0
        self.peak_connections = 0
        self.udp_dropped_answers = 0
        self._next_id = 1
        self._read_buffer = bytearray(_READ_SIZE)
        self._read_view = memoryview(self._read_buffer)
        self._server: asyncio.AbstractServer | None = None
        self._udp_transport: asyncio.DatagramTransport | None = None
        self._sweeper: asyncio.Task[None] | None = None
        self.loop: asyncio.AbstractEventLoop = None  # type: ignore[assignment]
        self._closing = False

    # -- lifecycle ------------------------------------------------------------------------------
    async def __aenter__(self) -> ReferenceBox:
        await self.start()
        return self

    async def __aexit__(self, *exc: object) -> None:
        await self.close()

    @property
    def address(self) -> tuple[str, int]:
        """(host, TCP port) once started."""
        if self.tcp_port is None:
            raise RuntimeError("the box is not started")
        return self.bound_host, self.tcp_port

    def describe(self) -> str:
        """``listening tcp HOST:PORT udp HOST:PORT`` (the ``serve`` command's first line)."""
        line = f"listening tcp {format_address(self.bound_host, self.tcp_port or 0)}"
        if self.udp_port is not None:
            line += f" udp {format_address(self.bound_host, self.udp_port)}"
        return line

    async def start(self) -> None:
        self.loop = asyncio.get_running_loop()
        target = self._log_target
        if target is not None:
            self.log = target if isinstance(target, FrameLog) else FrameLog(target)
        family, address = await self._resolve()
        self.bound_host = address
        attempts = 20 if self.port == 0 and self.udp and self.udp_port_request is None else 1
        for attempt in range(attempts):
            server = await self.loop.create_server(
                lambda: _TcpConnection(self), address, self.port, family=family, reuse_address=True, backlog=1024,
            )
            tcp_port = server.sockets[0].getsockname()[1]
            if not self.udp:
                break
            udp_port = tcp_port if self.udp_port_request is None else self.udp_port_request
            try:
                transport, _ = await self.loop.create_datagram_endpoint(
                    lambda: _UdpEndpoint(self), local_addr=(address, udp_port), family=family,
                )
            except OSError as exc:
                server.close()
                await server.wait_closed()
                if attempt + 1 < attempts:
                    continue
                raise OSError(exc.errno, f"cannot bind UDP {format_address(address, udp_port)}: {exc.strerror}") from None
            self._udp_transport = transport  # type: ignore[assignment]
            self.udp_port = transport.get_extra_info("sockname")[1]
            break
        self._server = server
        self.tcp_port = tcp_port
        self._sweeper = self.loop.create_task(self._sweep())

    async def _resolve(self) -> tuple[int, str]:
        """One local address for ``host`` (so that port 0 means one port for TCP and UDP)."""
        infos = await self.loop.getaddrinfo(self.host, None, type=socket.SOCK_STREAM, flags=socket.AI_PASSIVE)
        if not infos:
            raise OSError(f"cannot resolve {self.host!r}")
        family, _, _, _, sockaddr = infos[0]
        return int(family), str(sockaddr[0])

    async def close(self) -> None:
        """Stop listening, close every connection (answers already written are sent), flush the log."""
        if self._closing:
            return
        self._closing = True
        if self._sweeper is not None:
            self._sweeper.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await self._sweeper
        if self._server is not None:
            self._server.close()
        if self._udp_transport is not None:
            self._udp_transport.close()
        for conn in list(self.connections.values()):
            conn._close("box shutting down")
        # give the kernel the answers already written, then drop whoever is left
        deadline = self.loop.time() + 1.0
        while self.connections and self.loop.time() < deadline:
            await asyncio.sleep(0.01)
        for conn in list(self.connections.values()):
            if conn.transport is not None:
                conn.transport.abort()
        if self._server is not None:
            with contextlib.suppress(Exception):
                await asyncio.wait_for(self._server.wait_closed(), 2.0)
        await asyncio.sleep(0)
        if self.log is not None:
            self.log.close()

    # -- connection bookkeeping ---------------------------------------------------------------
    def _admit(self, conn: _TcpConnection) -> bool:
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

    def _victim(self) -> _TcpConnection | None:
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

    def _forget(self, conn: _TcpConnection, reason: str) -> None:
        if conn.id and self.connections.get(conn.id) is conn:
            del self.connections[conn.id]
        if conn.id:
            self._log_close(conn, reason)

    def _log_close(self, conn: _TcpConnection, reason: str) -> None:
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

    def summary(self) -> str:
        s = self.behaviour.stats
        return (
            f"connections accepted {self.accepted} (peak {self.peak_connections}, refused {self.refused}, "
            f"evicted {self.evicted}, idle-closed {self.idle_closed}); requests {s.requests}, answers {s.answers}, "
            f"malformed {s.malformed}, not requests {s.not_requests}, UDP dropped {s.dropped_datagrams}"
        )


class BoxThread:
    """A :class:`ReferenceBox` on its own thread and event loop, for synchronous code.

    ``BoxThread(config).start()`` returns once the box listens (on a free port by
    default); ``.address`` is ``(host, tcp_port)``; ``.stop()`` closes it.
    """

    def __init__(self, config: BoxConfig | None = None, *, port: int = 0, **box_kwargs: Any) -> None:
        self._kwargs = dict(box_kwargs, port=port)
        self._config = config
        self.box: ReferenceBox | None = None
        self._thread: threading.Thread | None = None
        self._ready = threading.Event()
        self._error: BaseException | None = None
        self._loop: asyncio.AbstractEventLoop | None = None
        self._stop: asyncio.Event | None = None

    def start(self, timeout: float = 10.0) -> BoxThread:
        if self._thread is not None:
            raise RuntimeError("already started")
        self._thread = threading.Thread(target=self._run, name="isight-reference-box", daemon=True)
        self._thread.start()
        if not self._ready.wait(timeout):
            raise TimeoutError("the reference box did not start")
        if self._error is not None:
            raise self._error
        return self

    def _run(self) -> None:
        loop = asyncio.new_event_loop()
        self._loop = loop
        try:
            loop.run_until_complete(self._main())
        except BaseException as exc:  # reported to start()
            self._error = exc
            self._ready.set()
        finally:
            loop.close()

    async def _main(self) -> None:
        self._stop = asyncio.Event()
        async with ReferenceBox(self._config, **self._kwargs) as box:
            self.box = box
            self._ready.set()
            await self._stop.wait()

    def stop(self, timeout: float = 10.0) -> None:
        loop, thread = self._loop, self._thread
        if loop is None or thread is None or not thread.is_alive():
            return
        stop = self._stop
        if stop is not None:
            with contextlib.suppress(RuntimeError):  # the loop already closed
                loop.call_soon_threadsafe(stop.set)
        thread.join(timeout)

    def call(self, func: Callable[[], Any]) -> Any:
        """Run ``func()`` on the box's loop and return its result (for tests)."""
        if self._loop is None:
            raise RuntimeError("not started")
        result: list[Any] = []
        done = threading.Event()

        def run() -> None:
            try:
                result.append(func())
            finally:
                done.set()

        self._loop.call_soon_threadsafe(run)
        done.wait(10.0)
        return result[0] if result else None

    @property
    def address(self) -> tuple[str, int]:
        assert self.box is not None, "not started"
        return self.box.address

    @property
    def tcp_port(self) -> int:
        assert self.box is not None and self.box.tcp_port is not None, "not started"
        return self.box.tcp_port

    @property
    def udp_port(self) -> int | None:
        assert self.box is not None, "not started"
        return self.box.udp_port

    @property
    def behaviour(self) -> BoxBehaviour:
        assert self.box is not None, "not started"
        return self.box.behaviour

    def __enter__(self) -> BoxThread:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()


# -- the serve command -------------------------------------------------------------------------------


def new_event_loop(kind: str = "asyncio") -> asyncio.AbstractEventLoop:
    """A fresh loop: ``asyncio`` (the standard one) or ``uvloop`` (if installed)."""
    if kind == "uvloop":
        try:
            import uvloop  # type: ignore[import-not-found]
        except ImportError:
            raise ValueError("--loop uvloop: uvloop is not installed (pip install uvloop)") from None
        return uvloop.new_event_loop()  # type: ignore[no-any-return]
    if kind != "asyncio":
        raise ValueError(f"unknown event loop {kind!r}")
    return asyncio.new_event_loop()


def run_loop(coro: Any, kind: str = "asyncio") -> Any:
    """``asyncio.run`` with a choice of loop (works on Python 3.10 too)."""
    loop = new_event_loop(kind)
    try:
        asyncio.set_event_loop(loop)
        return loop.run_until_complete(coro)
    finally:
        try:
            pending = [t for t in asyncio.all_tasks(loop) if not t.done()]
            for task in pending:
                task.cancel()
            if pending:
                loop.run_until_complete(asyncio.gather(*pending, return_exceptions=True))
            loop.run_until_complete(loop.shutdown_asyncgens())
        finally:
            asyncio.set_event_loop(None)
            loop.close()


def raise_fd_limit(wanted: int) -> None:
    """Raise the soft open-files limit towards ``wanted`` (never above the hard limit)."""
    try:
        import resource
    except ImportError:  # pragma: no cover (not POSIX)
        return
    soft, hard = resource.getrlimit(resource.RLIMIT_NOFILE)
    target = wanted if hard == resource.RLIM_INFINITY else min(wanted, hard)
    if soft != resource.RLIM_INFINITY and soft < target:
        with contextlib.suppress(ValueError, OSError):
            resource.setrlimit(resource.RLIMIT_NOFILE, (target, hard))


async def serve(box: ReferenceBox, out: IO[str] = sys.stdout, err: IO[str] = sys.stderr) -> int:
    """Run ``box`` until SIGINT/SIGTERM; print the listening line first. Returns 0."""
    stop = asyncio.Event()
    loop = asyncio.get_running_loop()
    installed = []
    for sig in (signal.SIGINT, signal.SIGTERM):
        with contextlib.suppress(NotImplementedError, RuntimeError, ValueError):
            loop.add_signal_handler(sig, stop.set)
            installed.append(sig)
    try:
        await box.start()
        print(box.describe(), file=out, flush=True)
        await stop.wait()
    finally:
        await box.close()
        for sig in installed:
            loop.remove_signal_handler(sig)
    print(f"isight-conformance serve: stopped; {box.summary()}", file=err, flush=True)
    return 0


def main_serve(
    config: BoxConfig, *, loop: str = "asyncio", out: IO[str] = sys.stdout, err: IO[str] = sys.stderr, **box_kwargs: Any
) -> int:
    """The ``serve`` subcommand: a box in the foreground until SIGINT/SIGTERM."""
    new_event_loop(loop).close()  # fail early and clearly on an unknown/missing loop
    raise_fd_limit(int(box_kwargs.get("max_connections", DEFAULT_MAX_CONNECTIONS)) + 64)
    box = ReferenceBox(config, **box_kwargs)
    return int(run_loop(serve(box, out, err), loop))


__all__ = [
    "BoxThread", "DEFAULT_MAX_CONNECTIONS", "DEFAULT_IDLE_TIMEOUT", "FrameLog", "ReferenceBox", "Transport",
    "format_address", "main_serve", "new_event_loop", "raise_fd_limit", "run_loop", "serve",
]

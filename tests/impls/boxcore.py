"""A threaded AI Box (server role) built on plain sockets: two threads per connection.

``ThreadBox(choices)`` listens on 127.0.0.1 port 0 (TCP, a second TCP port for the
stream when ``stream_port`` is "separate", and UDP when ``udp`` is "on"); use it as a
context manager or call ``start()``/``stop()``. On each connection a reader thread
frames what arrives (stamping when it arrived) and a writer thread sends each answer
once its latency has passed, in request order, so a constant latency never grows
on a pipelined stream. Every thread polls a stop event at least every 0.2 s and
every write is bounded, so ``stop()`` returns within about a second whatever the
peers do.
"""

from __future__ import annotations

import contextlib
import os
import queue
import socket
import struct
import threading
import time
from collections.abc import Callable

from .framers import Frame, Framer, LowByteLength
from .policy import Choices, Cycle, Reply, decide, decide_datagram
from .systematic import ConnState
from .udp_defects import reply_port
from .wire_format import HEADER_LEN

POLL = 0.2
WRITE_BOUND = 10.0  # seconds a peer may leave an answer unread before the box gives up on it
MAX_CONNECTIONS = 1024  # R5: beyond this the box closes new connections at once
LEAKY_LIMIT = 64
FLOOD_HEADER = bytes.fromhex("fefe00011023 01ffffff0000".replace(" ", ""))
LATENCY = {"0": 0.0, "2ms": 0.002, "20ms": 0.020, "100ms": 0.100}
PIECE_PAUSE = 0.005  # writer "pieces": the header, then the rest this long after
LINGER = 1.0  # seconds a closing box reads (and drops) what still comes before it closes
DROP_EVERY = 7  # drops-frames: every 7th answer on a connection is never written
QUIET_AFTER = 150  # quiet-after-n: after this many answers (the whole box) it answers nothing more
SHORT_SNDBUF = 4096  # short-send-drops: its small send buffer (the kernel doubles it)
#: the defects that send each answer once, non-blocking, and drop what the kernel did not take (EAGAIN or a part)
UNSENT_DROPPED = ("short-send-drops", "drops-unsendable")
GROW_S = 0.002  # latency-grows: each answer on a connection this much later than the one before
STALL_AT = 40  # stall-once: from the box-wide framer event (requests and bad bytes alike) it stalls ...
STALL_ON_CONN = 10  # ... at the first event that is at least this one on its connection (a connection in use, not a
#                     fresh one that asks once)
STALL_S = 6.0  # ... and for how long every connection goes unanswered


class ThreadBox:
    def __init__(self, choices: Choices, host: str = "127.0.0.1", port: int = 0) -> None:
        self.choices = choices
        self.stop_event = threading.Event()
        self.cycle = Cycle()
        self.lock = threading.Lock()
        self.conns: set[socket.socket] = set()
        self.threads: set[threading.Thread] = set()
        self.leaked: list[socket.socket] = []
        self.opened = 0
        self.listener = _listen(host, port)
        self.port: int = self.listener.getsockname()[1]
        self.listeners = [self.listener]
        self.stream_port: int | None = None
        if choices.stream_port == "separate":
            self.listeners.append(_listen(host, 0))
            self.stream_port = self.listeners[1].getsockname()[1]
        self.udp: socket.socket | None = None
        self.udp_port: int | None = None
        if choices.udp == "on":
            self.udp = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
            try:  # the same port number as TCP when it is free
                self.udp.bind((host, self.port))
            except OSError:
                self.udp.bind((host, 0))
            self.udp.settimeout(POLL)
            self.udp_port = self.udp.getsockname()[1]
        self._main: list[threading.Thread] = []
        self.answers = 0  # answers written (quiet-after-n)
        self.events = 0  # framer events taken, box-wide (stall-once)
        self.stall_until = 0.0  # stall-once: no answer is written before this (time.monotonic())
        self.stalled = False
        self._flood = os.urandom(1 << 16) if choices.defect == "flood-random" else FLOOD_HEADER * 4096

    # -- life cycle ---------------------------------------------------------------------------
    def __enter__(self) -> ThreadBox:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()

    def start(self) -> ThreadBox:
        targets: list[tuple[Callable[..., None], tuple[object, ...]]] = [(self._accept_loop, (lst,))
                                                                         for lst in self.listeners]
        targets += [(self._udp_loop, ())] if self.udp is not None else []
        for target, args in targets:
            thread = threading.Thread(target=target, args=args, name=f"box-{target.__name__}", daemon=True)
            thread.start()
            self._main.append(thread)
        return self

    def stop(self) -> None:
        self.stop_event.set()
        for thread in self._main:
            thread.join(5)
        for lst in self.listeners:
            with contextlib.suppress(OSError):
                lst.close()
        if self.udp is not None:
            with contextlib.suppress(OSError):
                self.udp.close()
        with self.lock:
            conns, threads = list(self.conns), list(self.threads)
        for conn in conns + self.leaked:
            with contextlib.suppress(OSError):
                conn.close()
        for thread in threads:
            thread.join(5)

    def wait(self, seconds: float) -> bool:
        """Sleep up to ``seconds``; True when the box is stopping."""
        return self.stop_event.wait(seconds)

    # -- accepting ------------------------------------------------------------------------------
    def _accept_loop(self, listener: socket.socket) -> None:
        while not self.stop_event.is_set():
            try:
                conn, _ = listener.accept()
            except TimeoutError:
                continue
            except OSError:
                return
            self.opened += 1
            defect = self.choices.defect
            if defect == "leaky" and self.opened > LEAKY_LIMIT or len(self.conns) >= MAX_CONNECTIONS:
                _reset(conn)
                continue
            if defect == "one-at-a-time":
                self._serve(conn)  # the next connection waits in the backlog until this one closes
                continue
            thread = threading.Thread(target=self._serve, args=(conn,), name="box-conn", daemon=True)
            with self.lock:
                self.threads.add(thread)
            thread.start()

    def _serve(self, conn: socket.socket) -> None:
        with self.lock:
            self.conns.add(conn)
        try:
            conn.settimeout(POLL)
            conn.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, int(self.choices.writer != "pieces"))
            if self.choices.defect == "short-send-drops":
                conn.setsockopt(socket.SOL_SOCKET, socket.SO_SNDBUF, SHORT_SNDBUF)
            defect = self.choices.defect
            if defect in ("flood-random", "flood-headers"):
                self._flood_loop(conn)
            else:
                self._read_loop(conn)
        except OSError:
            pass
        finally:
            with self.lock:
                self.conns.discard(conn)
                self.threads.discard(threading.current_thread())
            if self.choices.defect == "leaky":
                self.leaked.append(conn)  # never closed, never freed
            else:
                with contextlib.suppress(OSError):
                    conn.close()

    # -- one connection: a reader frames and decides, a writer answers when due ----------------------------
    def _read_loop(self, conn: socket.socket) -> None:
        answers: queue.Queue[tuple[float, Reply] | None] = queue.Queue()
        writer = threading.Thread(target=self._write_loop, args=(conn, answers), name="box-writer", daemon=True)
        writer.start()
        try:
            self._frame_loop(conn, answers)
        finally:
            answers.put(None)
            while writer.is_alive() and not self.stop_event.is_set():
                writer.join(POLL)
        self._linger(conn)

    def _linger(self, conn: socket.socket) -> None:
        """Before the close: read and drop what the peer still sends, until it closes (at most LINGER s). A close
        with unread bytes would be a reset, and a reset makes the peer's stack drop the answers not yet read."""
        deadline = time.monotonic() + LINGER
        while time.monotonic() < deadline and not self.stop_event.is_set():
            try:
                if not conn.recv(65536):
                    return
            except TimeoutError:
                continue
            except OSError:
                return

    def _frame_loop(self, conn: socket.socket, answers: queue.Queue[tuple[float, Reply] | None]) -> None:
        choices = self.choices
        framer = (LowByteLength if choices.defect == "low-byte-length" else Framer)(choices.has_extension, choices.framing)
        cycle = self.cycle if choices.cycle_scope == "box" else Cycle()
        latency = LATENCY[choices.latency] + choices.late * choices.time_out
        hung = choices.defect == "dead"
        remembers = ConnState()
        mangle = _Mangle(choices.defect)
        taken = 0  # framer events on this connection (stall-once)
        while not self.stop_event.is_set():
            try:
                data = conn.recv(65536)
            except TimeoutError:
                continue
            if not data:
                return
            arrived = time.monotonic()
            if hung or (choices.defect == "quiet-after-n" and self.answers >= QUIET_AFTER):
                continue  # read and discard: the connection stays open, silent
            if choices.defect == "split-header-lost" and not framer.buf and len(data) < HEADER_LEN:
                continue  # a read shorter than a header at the start of a frame is dropped
            framer.feed(data)
            answered = 0
            for event in framer.events():
                if choices.defect == "drops-rest-of-read" and isinstance(event, Frame):
                    framer.buf.clear()  # one whole frame per read: the rest of the read is discarded
                taken += 1
                self._count_event(arrived, taken)
                reply = decide(choices, event, cycle, remembers)
                if reply.hang:
                    hung = True
                    break
                if reply.close:
                    answers.put((arrived + latency, reply))
                    return
                if not reply.data:
                    continue
                answered += 1
                if choices.defect == "drops-coalesced" and answered > 1:
                    continue  # only the first frame of each read is answered
                data = mangle(reply.data)
                if data is None:
                    continue
                with self.lock:
                    self.answers += 1
                grow = GROW_S * mangle.count if choices.defect == "latency-grows" else 0.0
                due = max(arrived + latency + grow + reply.delay, self.stall_until)
                answers.put((due, Reply(data, reply.delay)))

    def _count_event(self, arrived: float, on_conn: int = 0) -> None:
        """stall-once: once, past the box's STALL_AT-th event, its whole loop blocks for STALL_S (every connection)."""
        with self.lock:
            self.events += 1
            if (self.choices.defect == "stall-once" and not self.stalled and self.events >= STALL_AT
                    and on_conn >= STALL_ON_CONN):
                self.stalled = True
                self.stall_until = arrived + STALL_S

    def _write_loop(self, conn: socket.socket, answers: queue.Queue[tuple[float, Reply] | None]) -> None:
        """Answers in order, each at its due time; a close reply shuts the connection (the reader ends)."""
        while not self.stop_event.is_set():
            try:
                item = answers.get(timeout=POLL)
            except queue.Empty:
                continue
            if item is None:
                return
            due, reply = item
            if self.wait(max(0.0, due - time.monotonic())):
                return
            if reply.close or not self._write(conn, reply.data):
                with contextlib.suppress(OSError):
                    conn.shutdown(socket.SHUT_WR)  # the FIN follows the answers; the reader lingers, then closes
                return

    def _write(self, conn: socket.socket, data: bytes) -> bool:
        """Write one answer the box's way; False when the peer is gone or the box stops."""
        defect, writer = self.choices.defect, self.choices.writer
        if defect == "slow-bytes":
            return all(self._send(conn, data[i : i + 1]) and not self.wait(0.5) for i in range(len(data)))
        if writer == "bytes":
            if not self._send(conn, data[:1]) or self.wait(0.010):
                return False
            return all(self._send(conn, data[i : i + 1]) for i in range(1, len(data)))
        if writer == "pieces":  # Nagle on: the header now, the blocks and the check once it is acknowledged
            return self._send(conn, data[:12]) and not self.wait(PIECE_PAUSE) and self._send(conn, data[12:])
        return self._send(conn, data)

    def _send(self, conn: socket.socket, data: bytes) -> bool:
        if self.choices.defect in UNSENT_DROPPED:  # one non-blocking send; what did not fit is dropped
            with contextlib.suppress(BlockingIOError), socket.socket(fileno=os.dup(conn.fileno())) as nb:
                nb.setblocking(False)  # this socket object never waits (the reader's keeps its timeout)
                nb.send(data)
            return True
        deadline = time.monotonic() + WRITE_BOUND
        view = memoryview(data)
        while view:
            if self.stop_event.is_set() or time.monotonic() > deadline:
                return False
            try:
                sent = conn.send(view)
            except TimeoutError:
                continue
            except (BrokenPipeError, ConnectionResetError):
                return False  # the peer went away (a repro replayed, a probe closed): nothing left to answer
            view = view[sent:]
        return True

    def _flood_loop(self, conn: socket.socket) -> None:
        """flood-random / flood-headers: write as fast as the peer reads, until it goes away."""
        data = memoryview(self._flood)
        offset = 0
        while not self.stop_event.is_set():
            try:
                offset = (offset + conn.send(data[offset:])) % len(data)
            except TimeoutError:
                continue

    def _udp_loop(self) -> None:
        udp = self.udp
        assert udp is not None
        while not self.stop_event.is_set():
            try:
                data, peer = udp.recvfrom(65536)
            except TimeoutError:
                continue
            except OSError:
                return
            self._count_event(time.monotonic())
            if self.wait(max(0.0, self.stall_until - time.monotonic())):
                return
            for out in decide_datagram(self.choices, data, self.cycle):
                with contextlib.suppress(OSError):
                    udp.sendto(out, (peer[0], reply_port(self.choices.defect, peer[1])))


class _Mangle:
    """Per connection: what the answer-mangling defects do to each answer (None: it is never written)."""

    def __init__(self, defect: str | None) -> None:
        self.defect = defect
        self.sticky = 0  # sticky-error: the last non-zero error code, never cleared
        self.count = 0

    def __call__(self, data: bytes) -> bytes | None:
        self.count += 1
        if self.defect == "drops-frames" and self.count % DROP_EVERY == 0:
            return None
        if self.defect == "sticky-error" and len(data) >= 12:
            code = int.from_bytes(data[10:12], "big")
            if code:
                self.sticky = code
            elif self.sticky:
                return data[:10] + self.sticky.to_bytes(2, "big") + data[12:]
        return data


def _listen(host: str, port: int) -> socket.socket:
    listener = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    listener.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    listener.bind((host, port))
    listener.listen(512)
    listener.settimeout(POLL)
    return listener


def _reset(conn: socket.socket) -> None:
    """Close with an RST (SO_LINGER 0): the connection is refused after being accepted."""
    with contextlib.suppress(OSError):
        conn.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, struct.pack("ii", 1, 0))
        conn.close()

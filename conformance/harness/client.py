"""Recorded connections to a box; what a box can do in answer are values (:mod:`.outcomes`, re-exported here).

Nothing a box does raises out of here: an answer, bytes that do not parse, silence
until the deadline, a close and a reset are all *values* (:data:`Outcome`). Only a
target that cannot be reached at all raises :class:`~.target.Unreachable`. Every
byte in and out is recorded in the case's :class:`~.transcript.Transcript`.
"""

from __future__ import annotations

import contextlib
import errno
import math
import select
import socket
import time
from collections.abc import Callable
from dataclasses import replace

from ..protocol import (
    CLOSED,
    HEADER_LEN,
    NEED_DATA,
    Frame,
    Profile,
    ProtocolError,
    StreamDecoder,
    TransferType,
    Transport,
    codec_for,
    peek_action,
    whole_frames,
)
from .outcomes import Answer, Closed, Malformed, Outcome, Silence
from .starvation import enable_rx_timestamps, recv_stamped
from .target import Refused, Target, Unreachable, connect_failure, dial
from .transcript import Endpoint, Kind, Transcript
from .udp_channel import UdpChannel

#: A box may send FLOOD_BYTES on one connection, plus FLOOD_PER_SENT times what the suite sent on it (answers
#: are no longer than the requests they answer); more is a flood: the suite stops reading and resets the
#: connection, having recorded the first bytes as evidence (bounded memory and disk). Descriptions quote at
#: most SHOWN_BYTES of what the box sent (.outcomes); drain() takes at most MAX_DRAIN outcomes (a box never quiet
#: ends it).
FLOOD_BYTES, FLOOD_PER_SENT, MAX_DRAIN = 64 * 1024, 4, 64


__all__ = ["Answer", "Closed", "Malformed", "Outcome", "Silence", "TcpConnection", "UdpChannel"]

# -- TCP ---------------------------------------------------------------------------------------


class TcpConnection:
    """One recorded TCP connection to the box (the robot's side)."""

    def __init__(
        self, transcript: Transcript, target: Target, profile: Profile, label: str = "", time_out_s: float | None = None
    ) -> None:
        self.transcript, self.target, self.profile, self.label = transcript, target, profile, label
        self.time_out_s = time_out_s if time_out_s is not None else profile.time_out_s
        self.codec = codec_for(profile)
        self.decoder = StreamDecoder(profile, expect=TransferType.BOX_TO_ROBOT)
        self.sock: socket.socket | None = None
        self.conn_id = 0
        self.closed_by_peer: Closed | None = None
        self._closed = False
        self.received_bytes = self.sent_bytes = 0
        self.max_bytes = FLOOD_BYTES
        #: called with every chunk before it is sent (the suite's session rules may stop a case here)
        self.before_send: Callable[[bytes], None] | None = None
        #: called with the action of every request :meth:`request` saw answered within the wait
        self.on_answered: Callable[[int], None] | None = None
        #: called when a wait for an answer runs out this connection's time_out (it may raise)
        self.on_time_out: Callable[[], None] | None = None
        self.before_connect: Callable[[socket.socket], None] | None = None  # e.g. a small SO_RCVBUF
        self.answers = 0  # answers (and malformed answers) read so far
        self.rx_at = self.last_arrival = math.inf  # when the last chunk, and the last answer returned, arrived
        #: bounded time (harness.waits): a short first wait for request()'s answer, on_cut(request, wait) when it ran
        #: out (it may raise), on_ran_out when the wait ran out time_out
        self.wait_bound: Callable[[TcpConnection], float | None] | None = None
        self.on_cut: Callable[[bytes, float], None] | None = None
        self.on_ran_out: Callable[[int], None] | None = None  # called with the answers read before
        self.stream_bound: float | None = None  # a pose stream's short wait for an overdue answer (harness.waits)
        #: ... and for the answer to a later frame of one write whose earlier frames were answered (R4, A1);
        #: on_coalesced(True) when such an answer came within time_out, on_coalesced(False) when it did not
        self.coalesced_bound: float | None = None
        self.on_coalesced: Callable[[bool], None] | None = None
        self.write_frames = 0  # whole frames at the start of the last write
        #: ... and for an answer to bytes last sent in pieces (R3: a box that loses a frame split inside its header
        #: leaves it unanswered in every case that splits); on_split(True/False) as on_coalesced, on_split_cut(wait)
        #: when the short wait ran out (it may raise)
        self.split_bound: Callable[[TcpConnection], float | None] | None = None
        self.on_split: Callable[[bool], None] | None = None
        self.on_split_cut: Callable[[float], None] | None = None
        #: the last bytes went out in pieces (send_pieces): "header" (the first piece shorter than a header),
        #: "body" (split after it), "" (not in pieces)
        self.split_write = ""
        self.answers_at_write = 0  # answers read before the last write

    # -- lifecycle -------------------------------------------------------------------------
    def connect(self) -> TcpConnection:
        start = time.monotonic()
        try:
            sock = dial(self.target, self.time_out_s, self.before_connect)
        except OSError as exc:
            info = self.transcript.open("tcp", Endpoint("0.0.0.0", 0), Endpoint(self.target.host, self.target.port), self.label)
            self.conn_id = info.conn
            if exc.errno in _RESET_AT_CONNECT:
                # the box accepted and reset at once (a race on a loaded machine, or a box that resets at
                # accept): the connection was reached, so this is what the box did, not an unreachable target
                self.transcript.add(info.conn, Kind.CONNECT, note=f"{self.label} reached the box")
                self._closed = True
                self._peer_gone(exc)
                return self
            reason = connect_failure(exc, self.time_out_s)
            self.transcript.add(info.conn, Kind.CONNECT_FAILED, note=reason)
            kind = Refused if isinstance(exc, ConnectionRefusedError) else Unreachable
            raise kind(f"cannot connect to {self.target}: {reason}") from None
        self.sock = sock
        gone: OSError | None = None
        try:
            sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            quick_ack(sock)
            sock.setblocking(False)
            enable_rx_timestamps(sock)
            local, remote = sock.getsockname(), sock.getpeername()
        except OSError as exc:  # the box reset the connection right after accepting it
            gone = exc
            local, remote = ("0.0.0.0", 0), (self.target.host, self.target.port)
            with contextlib.suppress(OSError):
                local = sock.getsockname()
        info = self.transcript.open("tcp", Endpoint(local[0], local[1]), Endpoint(remote[0], remote[1]), self.label)
        self.conn_id = info.conn
        self.transcript.add(self.conn_id, Kind.CONNECT, note=f"{self.label} connected in {(time.monotonic() - start) * 1000:.1f} ms")
        if gone is not None:
            self._peer_gone(gone)
        return self

    @property
    def is_open(self) -> bool:
        """Connected, and closed by neither side."""
        return self.sock is not None and not self._closed and self.closed_by_peer is None

    def close(self, note: str = "") -> None:
        """Close our side (FIN) and release the socket."""
        if self.sock is None or self._closed:
            return
        self._closed = True
        try:
            self.sock.shutdown(socket.SHUT_WR)
        except OSError:
            pass
        self.transcript.add(self.conn_id, Kind.CLOSE, note=note)
        self.sock.close()

    def abort(self, note: str = "") -> None:
        """Reset the connection (RST) instead of closing it."""
        if self.sock is None or self._closed:
            return
        self._closed = True
        try:
            self.sock.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, b"\x01\x00\x00\x00\x00\x00\x00\x00")
        except OSError:
            pass
        self.transcript.add(self.conn_id, Kind.ABORT, note=note)
        self.sock.close()

    def __enter__(self) -> TcpConnection:
        return self if self.sock is not None else self.connect()

    def __exit__(self, *exc: object) -> None:
        self.close()

    # -- sending ---------------------------------------------------------------------------
    def send(self, data: bytes | Frame, note: str = "") -> bool:
        """Write all of ``data``; False (and a recorded close/reset) if the box is gone."""
        if isinstance(data, Frame):
            data = self.codec.encode(data, Transport.TCP)
        if self.before_send is not None:
            self.before_send(data)
        if self.closed_by_peer and self.closed_by_peer.reset:
            return False
        assert self.sock is not None, "connect() first"
        view = memoryview(data)
        deadline = time.monotonic() + self.time_out_s
        sent = 0
        while sent < len(data):
            try:
                sent += self.sock.send(view[sent:])
            except BlockingIOError:
                if time.monotonic() > deadline:
                    break
                select.select([], [self.sock], [], 0.05)
            except OSError as exc:
                if sent:  # what went out before the reset, recorded before it
                    self.transcript.add(self.conn_id, Kind.SEND, data[:sent], note)
                self._peer_gone(exc)
                return False
        self.transcript.add(self.conn_id, Kind.SEND, data[:sent], note)
        self.sent_bytes += sent
        self.write_frames, self.answers_at_write = whole_frames(data, self.profile.byte_order), self.answers
        self.split_write = ""
        return sent == len(data)

    def send_pieces(self, pieces: list[bytes], gap_s: float = 0.0, note: str = "") -> bool:
        """Send bytes as separate segments (TCP_NODELAY), ``gap_s`` apart (R3)."""
        for i, piece in enumerate(pieces):
            if not self.send(piece, f"{note} piece {i + 1}/{len(pieces)}" if note else ""):
                return False
            if gap_s and i < len(pieces) - 1:
                time.sleep(gap_s)
        self.split_write = "" if len(pieces) < 2 else "header" if len(pieces[0]) < HEADER_LEN else "body"
        return True

    # -- receiving -------------------------------------------------------------------------
    def next_outcome(self, timeout_s: float | None = None, since: float | None = None) -> Outcome:
        """The box's next answer, malformed bytes, close, or silence until the deadline (time_out by default;
        for a later frame of a write whose earlier frames were answered, first the short coalesced_bound)."""
        if timeout_s is None and self._coalesced_wait():
            return self._coalesced_outcome(since)
        if timeout_s is None and self.split_write:
            return self._split_outcome(since)
        return self._next_outcome(timeout_s, since)

    def receive(self, deadline: float, since: float | None = None) -> Outcome:
        """What the box does next by ``deadline`` (``time.monotonic()``): an answer, malformed bytes, a close,
        or silence (:class:`~.connection.Connection`'s receive with a deadline)."""
        return self.next_outcome(max(0.0, deadline - time.monotonic()), since)

    def _split_outcome(self, since: float | None) -> Outcome:  # for bytes sent in pieces (R3)
        bound = self.split_bound(self) if self.split_bound is not None else None
        outcome = self._next_outcome(bound, since) if bound is not None else Silence(0.0)
        if bound is not None and isinstance(outcome, Silence) and self.on_split_cut is not None:
            self.on_split_cut(bound)  # the suite's rules may end the case here; else the wait goes on
        outcome = self._next_outcome(None, since) if isinstance(outcome, Silence) else outcome
        if self.on_split is not None and not isinstance(outcome, Closed):
            self.on_split(not isinstance(outcome, Silence))
        return outcome

    def _coalesced_wait(self) -> bool:  # for a frame that shared its write with frames already answered (R4)
        return self.write_frames > 1 and 0 < self.answers - self.answers_at_write < self.write_frames

    def _coalesced_outcome(self, since: float | None) -> Outcome:
        bound = self.coalesced_bound
        outcome = self._next_outcome(bound, since) if bound is not None else Silence(0.0)
        if bound is not None and isinstance(outcome, Silence) and self.on_cut is not None:
            self.on_cut(b"", bound)  # the suite's rules may end the case here; else the wait goes on
        outcome = self._next_outcome(None, since) if isinstance(outcome, Silence) else outcome
        if self.on_coalesced is not None and not isinstance(outcome, Closed):
            self.on_coalesced(not isinstance(outcome, Silence))
        return outcome

    def _next_outcome(self, timeout_s: float | None, since: float | None) -> Outcome:
        start = since if since is not None else time.monotonic()
        wait = self.time_out_s if timeout_s is None else timeout_s
        deadline = time.monotonic() + wait
        final = False  # at the deadline, one last look: the suite itself may have been kept from running
        while True:
            event = self.decoder.next_event()
            now = time.monotonic()
            arrived = min(now, self.rx_at)  # the kernel's receive time of the chunk that completed it
            if isinstance(event, Frame):
                self.answers, self.last_arrival = self.answers + 1, arrived
                return Answer(event, arrived - start, self.codec.encode_body(event) + event.check.to_bytes(2, "big"))
            if isinstance(event, ProtocolError):
                self.answers, self.last_arrival = self.answers + 1, arrived
                return Malformed(event, arrived - start)
            if event is CLOSED:
                return self.closed_by_peer or Closed(False, now - start)
            assert event is NEED_DATA
            if self.closed_by_peer is not None:
                return replace(self.closed_by_peer, latency_s=now - start)
            remaining = deadline - now
            if remaining <= 0 and not final and self.is_open:
                final = True
                self._read(0.0, start)
                if self.rx_at <= deadline:  # what came in time is taken (a stamp after the deadline stays unread)
                    continue
            if remaining <= 0 or self.sock is None or self._closed:
                if timeout_s is None and remaining <= 0:
                    if self.on_time_out is not None:
                        self.on_time_out()  # the suite's session rules may end the case here
                    self.transcript.timeouts += 1
                    self.transcript.note(f"no answer within time_out ({wait * 1000:.0f} ms)", self.conn_id)
                return Silence(time.monotonic() - start)
            self._read(remaining, start)

    def _read(self, wait_s: float, start: float) -> None:
        assert self.sock is not None
        try:
            ready, _, _ = select.select([self.sock], [], [], max(0.0, wait_s))
        except (OSError, ValueError):
            ready = []
        if not ready:
            return
        try:
            data, self.rx_at = recv_stamped(self.sock)
            quick_ack(self.sock)
        except BlockingIOError:
            return
        except OSError as exc:
            self._peer_gone(exc, start)
            self.decoder.receive_data(b"")
            return
        if data:
            self.transcript.add(self.conn_id, Kind.RECV, data)
            self.decoder.receive_data(data)
            self.received_bytes += len(data)
            if self.received_bytes > self.max_bytes + FLOOD_PER_SENT * self.sent_bytes:
                self._stop_flood(start)
        else:
            self.closed_by_peer = Closed(False, time.monotonic() - start)
            self.transcript.add(self.conn_id, Kind.PEER_CLOSE)
            self.decoder.receive_data(b"")

    def _stop_flood(self, start: float) -> None:
        """The box sent more than ``max_bytes``: stop reading, reset, and end the stream here."""
        self.closed_by_peer = Closed(False, time.monotonic() - start, flood=self.received_bytes)
        self.transcript.note(f"the box sent {self.received_bytes} bytes on this connection (the suite sent "
                             f"{self.sent_bytes}): a flood; the suite stops reading and resets the connection",
                             self.conn_id)
        self.abort("flood")
        self.decoder.receive_data(b"")

    def _peer_gone(self, exc: OSError, start: float | None = None) -> None:
        if self.closed_by_peer is not None:
            return
        reset = exc.errno in (errno.ECONNRESET, errno.EPIPE, errno.ECONNABORTED, errno.ENOTCONN)
        latency = time.monotonic() - start if start is not None else 0.0
        self.closed_by_peer = Closed(reset, latency)
        self.transcript.add(self.conn_id, Kind.PEER_RESET if reset else Kind.PEER_CLOSE, note=str(exc))

    def request(self, data: bytes | Frame, note: str = "", timeout_s: float | None = None) -> Outcome:
        """Send one request and wait for what follows (A1: one answer, T1: within time_out)."""
        start = time.monotonic()
        if not self.send(data, note):
            return self.closed_by_peer or Closed(False, time.monotonic() - start)
        raw = data if isinstance(data, bytes) else self.codec.encode(data)
        bound = self.wait_bound(self) if self.wait_bound is not None and timeout_s is None else None
        outcome = self.next_outcome(bound, since=start) if bound is not None else Silence(0.0)
        if bound is not None and isinstance(outcome, Silence) and self.on_cut is not None:
            self.on_cut(raw, bound)  # the suite's rules may end the case here; else the wait goes on
        outcome = self.next_outcome(timeout_s, since=start) if isinstance(outcome, Silence) else outcome
        if isinstance(outcome, Silence) and timeout_s is None and self.on_ran_out is not None:
            self.on_ran_out(self.answers)
        if self.on_answered is not None and isinstance(outcome, Answer) and outcome.frame.action == peek_action(raw):
            self.on_answered(outcome.frame.action)
        return outcome

    def drain(self, quiet_s: float = 0.05) -> list[Outcome]:
        """Everything the box sends until it has been quiet for ``quiet_s`` (at most
        :data:`MAX_DRAIN` outcomes, and no longer than time_out: a box that never goes quiet ends it)."""
        out: list[Outcome] = []
        deadline = time.monotonic() + max(self.time_out_s, quiet_s)
        while len(out) < MAX_DRAIN and time.monotonic() < deadline:
            outcome = self.next_outcome(quiet_s)
            if isinstance(outcome, Silence):
                return out
            out.append(outcome)
            if isinstance(outcome, Closed):
                return out
        return out

    def poll(self) -> list[Outcome]:
        """Outcomes already received or decodable now (never waits; at most :data:`MAX_DRAIN`)."""
        out: list[Outcome] = []
        if self.sock is not None and not self._closed and self.closed_by_peer is None:
            self._read(0.0, time.monotonic())
        while len(out) < MAX_DRAIN:
            outcome = self.next_outcome(0.0)
            if isinstance(outcome, Silence):
                break
            out.append(outcome)
            if isinstance(outcome, Closed):
                break
        return out


def quick_ack(sock: socket.socket) -> None:
    """ACK the box's bytes at once (Linux ``TCP_QUICKACK``, re-armed after every read): a box writing an answer
    in pieces with Nagle on waits for that ACK, and a delayed one (40 ms) would be charged to every answer."""
    if _QUICKACK is not None:
        with contextlib.suppress(OSError):
            sock.setsockopt(socket.IPPROTO_TCP, _QUICKACK, 1)


_QUICKACK: int | None = getattr(socket, "TCP_QUICKACK", None)
_RESET_AT_CONNECT = frozenset({errno.ECONNRESET, errno.EPIPE, errno.ECONNABORTED})

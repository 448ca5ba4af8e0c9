"""Backpressure (S6, R4, A1): the robot reads its answers late, or in small pieces, and the box keeps them all.

S6 lets a robot read the stream's answers late (pipelined). A box's answers then wait in
its send buffer; once that fills, ``send()`` writes less than asked (a non-blocking
socket) or blocks. A box that drops the part that did not fit cuts frames short and
loses answers, which no case that reads promptly ever sees. The drivers here make the
box's send buffer fill: the suite's receive buffer is small (``SO_RCVBUF``), and it reads
only when it has to (:func:`burst`), not at all for a while (:func:`late_stream`), or in
random small pieces (``pieces``). Everything read is kept as one byte stream;
:func:`judge_answers` decodes it and reports what S6/A1/F5 require: every answer intact,
in order, one per request, with the bytes (offsets and hex) of the first that is not.
"""

from __future__ import annotations

import random
import select
import socket
import time
from collections.abc import Callable
from dataclasses import dataclass, field

from ..harness.client import TcpConnection
from ..harness.transcript import Kind
from ..protocol import Frame, ProtocolError, StreamDecoder, TransferType
from ..protocol.constants import CHECK_LEN, HEADER_LEN

#: the suite's receive buffer in these cases (the kernel rounds it up to its minimum, about 2 KB)
SMALL_RCVBUF = 2048
#: a blockless answer's length (F5: 12 + 0 + 2)
ANSWER_LEN = HEADER_LEN + CHECK_LEN
#: how many bytes of the stream a finding quotes around the first bad answer
SHOWN = 48
#: the pace probe: this many poses pipelined and read at once, for at most PACE_S, before a burst
PACE_REQUESTS, PACE_S = 100, 2.0
#: a burst is sized so the box's measured pace answers it in about BURST_S, and never below MIN_BURST
BURST_S, MIN_BURST = 5.0, 500
#: however slowly a box answers, a backpressure exchange stops reading this long after its last send
#: (``Backlog.ended == "budget"``: the answers read are judged, the missing ones are not called lost)
BUDGET_S = 12.0


@dataclass
class Backlog:
    """What a backpressure exchange sent and read."""

    requests: int = 0  # requests sent whole
    sent_bytes: int = 0
    received: bytearray = field(default_factory=bytearray)
    reads: int = 0  # recv() calls that returned data
    ended: str = ""  # "", "closed", "reset", "silent" (time_out with answers still due), "blocked" (sends stalled),
    # "budget" (answers still coming when BUDGET_S ran out: too slow a box to wait for, not a lost answer)
    unread_s: float = 0.0  # how long the suite read nothing at the start
    elapsed_s: float = 0.0
    pace_hz: float = 0.0  # answers per second to the pace probe (0: no probe)
    last_read_at: float = 0.0  # time.monotonic() of the last recv() that returned data


@dataclass(frozen=True)
class Verdict:
    """The first thing wrong with the answers (None fields: all well)."""

    clause: str  # F5 (cut short / malformed), A1 (wrong, out of order, missing or extra), S6 (lost)
    expected: str
    observed: str
    received: bytes = b""


def small_rcvbuf(sock: socket.socket) -> None:
    """Before connect: the suite's receive buffer as small as the kernel allows (the window follows)."""
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, SMALL_RCVBUF)


def _read(conn: TcpConnection, out: Backlog, size: int) -> bool:
    """One recv of at most ``size`` bytes, recorded; False when the box closed or reset."""
    assert conn.sock is not None
    try:
        data = conn.sock.recv(size)
    except BlockingIOError:
        return True
    except OSError:
        out.ended = "reset"
        return False
    if not data:
        out.ended = "closed"
        return False
    conn.transcript.add(conn.conn_id, Kind.RECV, data)
    out.received += data
    out.reads += 1
    out.last_read_at = time.monotonic()
    return True


def _piece(rng: random.Random | None) -> int:
    return rng.randint(1, 24) if rng is not None else 65536


def pace(conn: TcpConnection, frame: bytes, expect_len: int, quiet_s: float, note: str = "") -> Backlog:
    """The box's pace on this connection: PACE_REQUESTS frames sent at once and their answers read as they come,
    for at most PACE_S. A box answering pipelined requests slowly (one at a time, with a pause) gets a smaller
    burst; its answers cannot back up into a full send buffer anyway, since the box itself is the bottleneck.
    When the answers stopped coming, the rest are awaited up to ``quiet_s`` after the last one, and no burst
    follows if they do not come (``ended == "silent"``: already answers lost, judged as the burst's would be)."""
    out, start = Backlog(), time.monotonic()
    if not conn.send(frame * PACE_REQUESTS, f"{note}: {PACE_REQUESTS} requests to measure the box's pace"):
        out.ended = "reset" if conn.closed_by_peer is not None and conn.closed_by_peer.reset else "closed"
        return out
    out.requests, out.sent_bytes = PACE_REQUESTS, len(frame) * PACE_REQUESTS
    want = PACE_REQUESTS * expect_len
    _read_rest(conn, out, want, PACE_S, None, deadline=start + PACE_S)
    out.ended = "" if out.ended in ("budget", "silent") else out.ended  # the pace alone judges nothing
    stopped_s = time.monotonic() - (out.last_read_at or start)
    if not out.ended and len(out.received) < want and stopped_s >= PACE_S / 2:
        _read_rest(conn, out, want, max(0.0, quiet_s - stopped_s), None, deadline=time.monotonic() + BUDGET_S)
    out.elapsed_s = time.monotonic() - start
    # the pace of the answers that came, up to the last one (a box that drops some is not taken for a slow one)
    out.pace_hz = len(out.received) / expect_len / max(out.last_read_at - start, 1e-3) if out.received else 0.0
    return out


def burst_size(pace_hz: float, most: int) -> int:
    """``most`` poses, or fewer (never below MIN_BURST) when the box's pace answers ``most`` in more than BURST_S."""
    return max(min(most, int(pace_hz * BURST_S)), min(MIN_BURST, most))


def burst(conn: TcpConnection, frames: list[bytes], expect_bytes: int, time_out_s: float,
          rng: random.Random | None = None, note: str = "", quiet_s: float | None = None,
          out: Backlog | None = None) -> Backlog:
    """Send every frame back to back, reading only when a send would block (so the box's send buffer fills),
    then read until ``expect_bytes`` arrived (in all, ``out``'s earlier reads included), the box closed, nothing
    came for ``quiet_s`` (default ``time_out_s``) or BUDGET_S ran out. ``rng``: every read takes a random 1..24
    bytes (split reads)."""
    assert conn.sock is not None
    out, start = out or Backlog(), time.monotonic()
    sock, data = conn.sock, b"".join(frames)
    view, sent, stalled_since = memoryview(data), 0, None
    while sent < len(data) and not out.ended:
        try:
            n = sock.send(view[sent:sent + 65536])
            conn.transcript.add(conn.conn_id, Kind.SEND, bytes(view[sent:sent + n]), note)
            sent, stalled_since = sent + n, None
            continue
        except BlockingIOError:
            pass
        except OSError:
            out.ended = "reset"
            break
        stalled_since = stalled_since or time.monotonic()
        if time.monotonic() - stalled_since > time_out_s:
            out.ended = "blocked"  # neither reading nor writable for time_out: the box stopped reading
            break
        readable, _, _ = select.select([sock], [], [], 0.05)
        if readable:
            _read(conn, out, _piece(rng))
    conn.sent_bytes += sent
    out.sent_bytes += sent
    out.requests += _whole(frames, sent)
    _read_rest(conn, out, expect_bytes, time_out_s if quiet_s is None else quiet_s, rng,
               deadline=time.monotonic() + BUDGET_S)
    out.elapsed_s += time.monotonic() - start
    return out


def late_stream(conn: TcpConnection, frame_at: Callable[[int], bytes], rate_hz: float, unread_s: float,
                expect_len: int, time_out_s: float, note: str = "", quiet_s: float | None = None) -> Backlog:
    """Stream one request every 1/rate for ``unread_s`` seconds reading nothing (the box's answers back up),
    then read everything (``expect_len`` bytes per request sent) until it all came, a close, or time_out."""
    assert conn.sock is not None
    out, start = Backlog(), time.monotonic()
    period = 1.0 / rate_hz
    while time.monotonic() - start < unread_s and not out.ended:
        due = start + out.requests * period
        time.sleep(max(0.0, due - time.monotonic()))
        data = frame_at(out.requests)
        if not conn.send(data, f"{note}: request {out.requests + 1}, answers left unread"):
            out.ended = "reset" if conn.closed_by_peer is not None and conn.closed_by_peer.reset else "blocked"
            break
        out.requests += 1
        out.sent_bytes += len(data)
    out.unread_s = time.monotonic() - start
    _read_rest(conn, out, out.requests * expect_len, time_out_s if quiet_s is None else quiet_s, None,
               deadline=time.monotonic() + BUDGET_S)
    out.elapsed_s = time.monotonic() - start
    return out


def _whole(frames: list[bytes], sent: int) -> int:
    count = 0
    for frame in frames:
        sent -= len(frame)
        if sent < 0:
            break
        count += 1
    return count


def _read_rest(conn: TcpConnection, out: Backlog, expect_bytes: int, time_out_s: float,
               rng: random.Random | None, deadline: float) -> None:
    """Read until ``expect_bytes`` arrived, a close, nothing for ``time_out_s`` ("silent") or ``deadline``
    while answers still come ("budget")."""
    assert conn.sock is not None
    last = time.monotonic()
    while len(out.received) < expect_bytes and not out.ended:
        readable, _, _ = select.select([conn.sock], [], [], 0.05)
        now = time.monotonic()
        if readable:
            if _read(conn, out, _piece(rng)):
                last = now
        elif now - last > time_out_s:
            out.ended = "silent"
        if not out.ended and now > deadline and len(out.received) < expect_bytes:
            out.ended = "budget"


def judge_answers(out: Backlog, action: int, requests: int) -> Verdict | None:
    """The first thing wrong with the answers read: cut short or malformed (F5), not the expected answer
    (A1), fewer than the requests (S6, A1: lost), or more (A1). None: every answer intact, in order, one each."""
    decoder = StreamDecoder(expect=TransferType.BOX_TO_ROBOT)
    events = decoder.feed(bytes(out.received))
    offset, good = 0, 0
    for event in events:
        if isinstance(event, ProtocolError):
            at = event.offset or offset
            return Verdict("F5", f"answer {good + 1} a whole frame (12 + N×L + 2 bytes)",
                           f"after {good} intact answer(s), at byte {at} of {len(out.received)} read: {event}",
                           _around(out.received, at))
        assert isinstance(event, Frame)
        size = HEADER_LEN + len(event.blocks) * event.block_length + CHECK_LEN
        if int(event.action) != action or event.error_code != 0:
            return Verdict("A1", f"answer {good + 1} echoes action {action:02X} with error 0000 (in request order)",
                           f"answer {good + 1} at byte {offset}: {event.describe()}", _around(out.received, offset))
        offset += size
        good += 1
    tail = decoder.buffered
    if good < requests and out.ended == "budget":
        return None  # answers still coming, all intact so far: too slow to wait for, not lost (the case says so)
    if good < requests:
        why = {"closed": "then the box closed the connection", "reset": "then the box reset the connection",
               "silent": "then nothing more came for time_out", "blocked": "the box stopped reading"}.get(out.ended, "")
        cut = f"; the last {tail} byte(s) are a frame cut short (F5)" if tail else ""
        return Verdict("S6", f"{requests} answers, one per request, however late the robot reads them",
                       f"{good} intact answers ({len(out.received)} bytes of the {requests * ANSWER_LEN} due): "
                       f"{requests - good} lost{cut}" + (f"; {why}" if why else ""),
                       _around(out.received, max(0, offset - 14)))
    if good > requests:
        return Verdict("A1", f"{requests} answers, one per request", f"{good} answers", b"")
    return None


def _around(data: bytearray, offset: int) -> bytes:
    return bytes(data[max(0, offset - 14) : offset + SHOWN])

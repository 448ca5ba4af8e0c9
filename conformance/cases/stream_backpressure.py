"""S6/R4/A1 under backpressure: the robot reads late or in small pieces, and the box keeps every answer.

Every other case reads its answers promptly, so the box's send buffer never fills. Here
the suite's receive buffer is small (``SO_RCVBUF``) and it reads late: a stream read after
time_out, a burst of thousands of pipelined poses read only when the suite could not
send, and the same burst read in random pieces of 1 to 24 bytes. A box that drops what a
short ``send()`` did not write cuts frames (F5) and loses answers (S6, A1).
"""

from __future__ import annotations

import random
import select
import socket
import time
from collections.abc import Callable
from dataclasses import dataclass, field

from conformance.protocol import Action, Frame, ProtocolError, StreamDecoder, TransferType, encode, request
from conformance.protocol.constants import CHECK_LEN, HEADER_LEN
from conformance.suite import (
    DEFAULT_POSE,
    STREAM,
    CaseContext,
    Inconclusive,
    Kind,
    Level,
    Requirement,
    Sig,
    Signature,
    TcpConnection,
    case,
    responsive,
)

# -- the family's helpers: Backpressure (S6, R4, A1): the robot reads its answers late, or in small pieces, and the box keeps them all.
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


# -- the cases

#: how many poses a burst pipelines (each answer 14 bytes: about 40 KB of answers behind a 2 KB window); fewer
#: when the box's pace (pace) would take more than a few seconds to answer them
BURST = 3000
#: one root cause for the backpressure verdicts: answers the box never delivered whole once the robot read late
LOST = Signature(Sig.SILENCE, "every POSE when the robot reads late (S6)")
CHECKS = {"F5": Requirement(("F5", "S6"), "every answer the box writes is a whole frame, however late the robot reads"),
          "A1": Requirement(("A1", "S6"), "one answer per request, in request order, each 0000"),
          "S6": Requirement(("S6", "A1"), "the box keeps every answer however late the robot reads them")}


def _connect(isight: CaseContext, label: str) -> TcpConnection:
    return isight.connect(label, target=isight.session.stream_target(), prepare=small_rcvbuf)


def _pose(isight: CaseContext) -> bytes:
    return encode(request(Action.POSE, isight.codec.pose_blocks([DEFAULT_POSE])), isight.profile)


#: why a wait was cut short (harness.waits): streams, or several requests in one write, of earlier FAILed cases
STREAMS_LEFT = "streams of earlier cases left a pose unanswered for the whole time_out"
WRITES_LEFT = "earlier cases' requests sent several in one write were left unanswered after the first (R4)"


def _quiet_s(isight: CaseContext, conn: TcpConnection, one_write: bool = False) -> tuple[float, str]:
    """How long to wait for answers still due, and why it is short: time_out, or 1 s once two FAILed cases left a
    stream's pose unanswered for the whole time_out, or (``one_write``: a burst) a later frame of one write."""
    if one_write and conn.coalesced_bound is not None and conn.coalesced_bound < isight.time_out_s:
        return conn.coalesced_bound, WRITES_LEFT
    if conn.stream_bound is not None and conn.stream_bound < isight.time_out_s:
        return conn.stream_bound, STREAMS_LEFT
    return isight.time_out_s, ""


def _judge(isight: CaseContext, conn: TcpConnection, out: Backlog, what: str, quiet: tuple[float, str]) -> None:
    quiet_s, why = quiet
    isight.details[what] = {"requests": out.requests, "sent_bytes": out.sent_bytes, "received_bytes": len(out.received),
                            "reads": out.reads, "unread_s": round(out.unread_s, 3), "elapsed_s": round(out.elapsed_s, 3),
                            "pace_hz": round(out.pace_hz, 1), "ended": out.ended or "normally"}
    bad = judge_answers(out, int(Action.POSE), out.requests)
    if bad is None and out.ended == "budget":
        raise Inconclusive(f"{what}: {len(out.received) // ANSWER_LEN} of {out.requests} answers read in "
                           f"{BUDGET_S:.0f} s, every one intact and in order, and more still coming: too slow to wait "
                           "for in bounded time, so the rest were not judged", judged=("S6",))
    if bad is not None and out.ended == "silent" and quiet_s < isight.time_out_s:
        isight.close_all()
        if responsive(isight.check_alive()):
            seen = bad.observed.replace("; then nothing more came for time_out", "")
            raise Inconclusive(f"{what}: {seen}, nothing more within {quiet_s * 1000:.0f} ms; {why} (the box still "
                               "answers a fresh connection), so the wait ended there, not judged", signature=LOST,
                               judged=("S6",))
    if bad is not None and out.ended == "silent" and conn.on_ran_out is not None:
        conn.on_ran_out(STREAM)  # a stream left unanswered for time_out: the pattern counts if this case FAILs
    if bad is not None:
        raise isight.broken(bad.clause, expected=bad.expected, observed=f"{what}: {bad.observed}",
                            received=bad.received, sent=_pose(isight), signature=LOST)


@case("S6-02", ["S6", "A1", "F5", "T2"], Level.MUST, "A stream read late: every answer kept, intact and in order",
      "poses at the profile rate for time_out with nothing read (the suite's receive buffer small), then everything "
      "read: one intact 0000 answer per pose, in order", checks=CHECKS)
def test_stream_read_late(isight: CaseContext) -> None:
    conn = _connect(isight, "stream (read late)")
    pose = _pose(isight)
    quiet = _quiet_s(isight, conn)
    out = late_stream(conn, lambda i: pose, isight.profile.pose_rate_hz, isight.time_out_s, ANSWER_LEN,
                      isight.time_out_s, "stream read late", quiet[0])
    _judge(isight, conn, out, "stream read late", quiet)


@case("S6-03", ["S6", "R4", "A1", "F5"], Level.MUST, "A burst of pipelined poses behind a small receive window",
      f"a pace probe of {PACE_REQUESTS} poses, then {BURST} (fewer from a box too slow to answer them in seconds) sent "
      "back to back, the suite reading only when it cannot send (its receive buffer small, so the box's send buffer "
      "fills): one intact 0000 answer per pose, in order", checks=CHECKS)
def test_burst(isight: CaseContext) -> None:
    conn = _connect(isight, "stream (burst)")
    quiet = _quiet_s(isight, conn, one_write=True)
    out = _burst(isight, conn, quiet[0], None, "burst")
    _judge(isight, conn, out, "burst", quiet)


@case("S6-04", ["S6", "R4", "A1", "F5"], Level.MUST, "The burst read in random small pieces",
      f"the pace probe, then {BURST} poses (fewer from a slow box) sent back to back, the answers read in random "
      "pieces of 1 to 24 bytes (receive buffer small): "
      "one intact 0000 answer per pose, in order", checks=CHECKS)
def test_split_reads(isight: CaseContext) -> None:
    conn = _connect(isight, "stream (split reads)")
    quiet = _quiet_s(isight, conn, one_write=True)
    out = _burst(isight, conn, quiet[0], random.Random(isight.settings.seed), "burst, split reads")
    _judge(isight, conn, out, "split reads", quiet)


def _burst(isight: CaseContext, conn: TcpConnection, quiet: float, rng: random.Random | None, note: str) -> Backlog:
    """The pace probe, then the burst sized to it (BURST poses from a box that answers them in a few seconds)."""
    pose = _pose(isight)
    out = pace(conn, pose, ANSWER_LEN, quiet, note)
    if out.ended:
        return out
    size = burst_size(out.pace_hz, BURST)
    return burst(conn, [pose] * size, (out.requests + size) * ANSWER_LEN, isight.time_out_s, rng, note, quiet, out)

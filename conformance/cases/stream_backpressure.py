"""S6/R4/A1 under backpressure: the robot reads late or in small pieces, and the box keeps every answer.

Every other case reads its answers promptly, so the box's send buffer never fills. Here
the suite's receive buffer is small (``SO_RCVBUF``) and its segments Ethernet-sized
(``TCP_MAXSEG`` 1460: on loopback's 64 KiB segments a box's kernel would take hundreds of
thousands of unread answers before refusing one), and it reads late: a stream read after
time_out, a burst of thousands of pipelined poses read only when the suite could not
send, the same burst read in random pieces of 1 to 24 bytes, and (S6-05) mixed requests
streamed unread until the box stops reading or a bound passes. A box that drops what a
``send()`` did not take at once cuts frames (F5) and loses answers (S6, A1); the mixed
actions of S6-05 tell which answer was lost first (``suite/answer_runs.py``).
"""

from __future__ import annotations

import bisect
import contextlib
import itertools
import random
import select
import socket
import struct
import time
from collections.abc import Callable, Sequence

try:  # the answers waiting unread (S6-05's hold): POSIX
    import fcntl
    import termios
except ImportError:  # pragma: no cover - Windows
    pass

from conformance.protocol import (
    Action,
    encode,
    request,
)
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
from conformance.suite.answer_runs import ANSWER_LEN, Backlog, judge_answers

# -- the family's helpers: Backpressure (S6, R4, A1): the robot reads its answers late, or in small pieces, and the box keeps them all.
#: the suite's receive buffer in these cases (the kernel rounds it up to its minimum, about 2 KB)
SMALL_RCVBUF = 2048
#: the TCP segment size of Ethernet (1500-byte MTU less 40 bytes of IP and TCP headers)
ETHERNET_MSS = 1460
#: the pace probe: this many poses pipelined and read at once, for at most PACE_S, before a burst
PACE_REQUESTS, PACE_S = 100, 2.0
#: a burst is sized so the box's measured pace answers it in about BURST_S, and never below MIN_BURST
BURST_S, MIN_BURST = 5.0, 500
#: however slowly a box answers, a backpressure exchange stops reading this long after its last send
#: (``Backlog.ended == "budget"``: the answers read are judged, the missing ones are not called lost)
BUDGET_S = 12.0


def small_rcvbuf(sock: socket.socket) -> None:
    """Before connect: the suite's receive buffer as small as the kernel allows (the window follows), and Ethernet
    segments (TCP_MAXSEG 1460, where the platform has it) as a robot on a wire would have them: the box's kernel
    then keeps its unsent answers in segment-sized buffers, so its send buffer fills after thousands of unread
    answers, where on loopback (64 KiB segments) it would take hundreds of thousands."""
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, SMALL_RCVBUF)
    if hasattr(socket, "TCP_MAXSEG"):
        with contextlib.suppress(OSError):
            sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_MAXSEG, ETHERNET_MSS)


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
    out.first_read_at = out.first_read_at or out.last_read_at
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


def unread_stream(conn: TcpConnection, chunk: bytes, ends: Sequence[int], most: int, out: Backlog,
                  note: str = "") -> int:
    """Send ``chunk`` (whole requests ending at the offsets ``ends``) again and again, reading nothing, for
    UNREAD_S or ``most`` requests at most (recorded in ``out``); it ends early once sends have been refused for
    CLOSED_S (the window closed: the box stopped reading). Returns how many requests were sent whole."""
    assert conn.sock is not None
    sock, start, sent, requests = conn.sock, time.monotonic(), 0, 0
    whole, rest = divmod(most, len(ends))
    limit = whole * len(chunk) + (ends[rest - 1] if rest else 0)  # the bytes of ``most`` requests
    stalled_since: float | None = None
    while time.monotonic() - start < UNREAD_S and sent < limit:
        at = sent % len(chunk)
        try:
            n = sock.send(memoryview(chunk)[at : at + limit - sent])
        except BlockingIOError:
            stalled_since = stalled_since or time.monotonic()
            if time.monotonic() - stalled_since > CLOSED_S:
                break  # the window closed: the box stopped reading, its answers back up
            select.select([], [sock], [], 0.02)
            continue
        except OSError:
            out.ended = "reset"
            break
        conn.transcript.add(conn.conn_id, Kind.SEND, chunk[at : at + n], note)
        sent, stalled_since = sent + n, None
        whole, rest = divmod(sent, len(chunk))
        requests = whole * len(ends) + bisect.bisect_right(ends, rest)
    else:  # every request sent: still nothing read until the box's answers stop coming in (it cannot send more)
        _hold(sock, start)
    conn.sent_bytes += sent
    out.sent_bytes += sent
    out.requests += requests
    out.unread_s = time.monotonic() - start
    return requests


def _hold(sock: socket.socket, start: float) -> None:
    """Read nothing until the answers waiting in the suite's receive buffer have not grown for CLOSED_S (the window
    closed, or the box answered everything), or UNREAD_S since ``start``."""
    last, since = -1, time.monotonic()
    while time.monotonic() - start < UNREAD_S:
        try:
            waiting = struct.unpack("i", fcntl.ioctl(sock.fileno(), termios.FIONREAD, b"\0\0\0\0"))[0]
        except (OSError, NameError):
            return  # the platform does not tell: no hold
        if waiting != last:
            last, since = waiting, time.monotonic()
        elif waiting and time.monotonic() - since > CLOSED_S:
            return
        time.sleep(0.02)


def throughput(out: Backlog) -> float:
    """The pace probe's answers per second from the first to the last one (a box's latency is not its pace), or its
    pace when they came at once."""
    answers = len(out.received) // ANSWER_LEN
    if answers < 2 or out.last_read_at - out.first_read_at < 1e-3:
        return out.pace_hz if answers < 2 else float(UNREAD_MAX)
    return max(out.pace_hz, (answers - 1) / (out.last_read_at - out.first_read_at))


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




# -- the cases

#: how many poses a burst pipelines (each answer 14 bytes: about 40 KB of answers behind a 2 KB window); fewer
#: when the box's pace (pace) would take more than a few seconds to answer them
BURST = 3000
#: S6-05: the actions streamed unread (each answered 0000 in any cycle state: A4, S3), in a seeded order of PATTERN
#: requests sent again and again, so that where answers were lost shows in the answers' actions
MIXED, PATTERN = (Action.POSE, Action.REGISTER_POSE, Action.TOLERANCE, Action.NONE), 2048
#: S6-05's unread stream: at most UNREAD_MAX requests (their answers 280 KB: a box sending each answer at once to a
#: 1460-byte-segment peer finds its default send buffer full after about 2 500 unread) and UNREAD_S seconds; the window
#: is closed once sends have been refused for CLOSED_S (a box that stops reading while its answers back up)
UNREAD_MAX, UNREAD_S, CLOSED_S = 20_000, 2.0, 0.3
#: ... and no more requests than the box's pace (the pace probe's) answers in UNREAD_PACE_S, nor fewer than UNREAD_MIN:
#: a slow box is its own bottleneck (its answers cannot back up), and one that writes byte by byte reads slower still
UNREAD_PACE_S, UNREAD_MIN = 1.0, 300
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


def _judge(isight: CaseContext, conn: TcpConnection, out: Backlog, what: str, quiet: tuple[float, str],
           actions: Sequence[int] | None = None) -> None:
    quiet_s, why = quiet
    isight.details[what] = {"requests": out.requests, "sent_bytes": out.sent_bytes, "received_bytes": len(out.received),
                            "reads": out.reads, "unread_s": round(out.unread_s, 3), "elapsed_s": round(out.elapsed_s, 3),
                            "pace_hz": round(out.pace_hz, 1), "ended": out.ended or "normally"}
    bad = judge_answers(out, int(Action.POSE) if actions is None else actions, out.requests)
    if bad is None and out.ended == "budget":
        raise Inconclusive(f"{what}: {len(out.received) // ANSWER_LEN} of {out.requests} answers read in "
                           f"{BUDGET_S:.0f} s, every one intact and in order, and more still coming: too slow to wait "
                           "for in bounded time, so the rest were not judged", judged=("S6",))
    if bad is not None and bad.shortfall and out.ended == "silent" and quiet_s < isight.time_out_s:
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


@case("S6-05", ["S6", "A1", "F5", "R4"], Level.MUST, "A stream left unread until the window closes, at Ethernet sizes",
      f"the pace probe, then mixed requests (POSE, RegisterPose, Tolerance, NONE in a seeded order) streamed back to "
      f"back with nothing read (TCP_MAXSEG 1460 and a small receive buffer on the suite's socket) until the box stops "
      f"reading or {UNREAD_MAX} requests (fewer to a slow box) / {UNREAD_S} s, then everything read: one intact 0000 answer per request, in order "
      "(a box that drops the answers it cannot send at once loses them; the first lost one is named)", checks=CHECKS)
def test_unread_until_the_window_closes(isight: CaseContext) -> None:
    conn, start = _connect(isight, "stream (unread until the window closes)"), time.monotonic()
    quiet = _quiet_s(isight, conn, one_write=True)
    rng = random.Random(isight.settings.seed)
    actions = [rng.choice(MIXED) for _ in range(PATTERN)]
    codec = isight.codec
    frames = {a: encode(request(a, codec.pose_blocks([DEFAULT_POSE]) if a in (Action.POSE, Action.REGISTER_POSE)
                                else codec.tolerance_blocks([0.5]) if a is Action.TOLERANCE else ()), isight.profile)
              for a in MIXED}
    note = "stream unread until the window closes"
    out = pace(conn, frames[Action.POSE], ANSWER_LEN, quiet[0], note)  # a slow box gets fewer requests
    probe, sent = out.requests, 0
    if not out.ended:
        chunk, ends = b"".join(frames[a] for a in actions), list(itertools.accumulate(len(frames[a]) for a in actions))
        most = max(min(UNREAD_MAX, int(throughput(out) * UNREAD_PACE_S)), UNREAD_MIN)
        sent = unread_stream(conn, chunk, ends, most, out, note)
    if not out.ended:
        _read_rest(conn, out, out.requests * ANSWER_LEN, quiet[0], None, deadline=time.monotonic() + BUDGET_S)
    out.elapsed_s = time.monotonic() - start
    _judge(isight, conn, out, "unread stream", quiet,
           [int(Action.POSE)] * probe + [int(actions[i % PATTERN]) for i in range(sent)])

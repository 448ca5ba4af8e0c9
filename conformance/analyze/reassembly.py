"""TCP reassembly for one connection, both directions (sans-I/O).

:class:`TcpStream` takes the segments of one connection in capture order and hands
its sink each direction's bytes in stream order, exactly once:

* **retransmissions** (and duplicates, as a mirror port makes) are dropped; where the
  bytes a retransmission repeats are still known (the last :data:`RECENT` segments of
  the direction) they are compared, and a difference is reported (``conflict``);
* **out-of-order** segments wait until the bytes before them arrive;
* **gaps**: bytes the capture does not have. The evidence is the receiver's ACK: when
  one side acknowledges bytes of the other that the capture has not shown, those bytes
  reached the receiver but not the capture. After a short grace (a capture may show
  segments a little out of order: :data:`REORDER_PACKETS` packets or
  :data:`REORDER_S` seconds) the missing range is declared a gap (``gap``) and the
  stream resumes after it. Without ACK evidence a hole that lasts
  :data:`STALL_PACKETS` packets, or holds more than :data:`OOO_LIMIT` bytes waiting,
  is a gap too. Bytes cut by the snap length are handed on at once as a count (``snap``);
* **causal order across directions**: bytes of one side whose segment acknowledges
  bytes of the other side not yet handed on are held back until those are (or are
  declared a gap), so an answer is never delivered before the request it answers, nor
  the next request before that answer, even when the capture shows them the other way
  round.

Everything held is bounded (out-of-order bytes, held-back bytes, the recent bytes),
so the state of a connection does not grow with its length.

The bytes go to ``feed[d](payload, frame, ts)``; the sink has ``gap(d, nbytes,
frame_before, frame_after, ts)``, ``snap(d, nbytes, frame, ts)`` (bytes of that frame the
snap length cut), ``close(d, how, frame, ts)`` (``how`` is ``"fin"`` or
``"rst"``), ``conflict(d, frame, ts)`` and ``midstart(d)`` (the direction's first bytes
did not follow its SYN); ``d`` is 0 or 1, the direction of the
connection's first packet or its reverse. The in-order case (nearly every segment)
takes a short path at the top of :meth:`TcpStream.segment`.
"""

from __future__ import annotations

from collections import deque
from typing import Any

from .capture_packets import ACK, FIN, RST, SYN

__all__ = ["DONE", "RESTART", "TcpStream", "REORDER_PACKETS", "REORDER_S", "STALL_PACKETS", "OOO_LIMIT", "RECENT"]

MASK = 0xFFFFFFFF
HALF = 1 << 31
REORDER_PACKETS = 32
REORDER_S = 0.5
STALL_PACKETS = 4096
OOO_LIMIT = 1 << 20
PENDING_LIMIT = 1 << 18
RECENT = 64  # segments kept per direction to compare retransmissions with
#: ``segment`` returns this for a SYN that starts a new connection on the same addresses and ports
RESTART = "restart"
#: ``segment`` returns this when the connection has ended (reset, or closed both ways)
DONE = "done"
_DATA, _GAP, _FIN, _SNAP = 0, 1, 2, 3


def _behind(a: int, b: int) -> bool:
    """Sequence number ``a`` is before ``b`` (modulo 2**32)."""
    return 0 < ((b - a) & MASK) < HALF


class Direction:
    __slots__ = ("next", "isn", "ooo", "ooo_bytes", "acked", "hole_pkt", "hole_ts", "hole_no", "closed",
                 "recent", "pending", "pending_bytes", "emitted", "last_no", "midstart", "seen")

    def __init__(self) -> None:
        self.next: int | None = None  # next expected sequence number
        self.isn: int | None = None
        #: seq -> (payload, missing, frame, ts, fin, ack)
        self.ooo: dict[int, tuple[bytes, int, int, float, bool, int | None]] = {}
        self.ooo_bytes = 0
        self.acked: int | None = None  # the other side's highest ACK of this direction
        self.hole_pkt: int | None = None  # packet count when the current hole was first seen
        self.hole_ts = 0.0
        self.hole_no = 0
        self.closed = False  # FIN reached
        self.recent: deque[tuple[int, bytes]] = deque(maxlen=RECENT)  # the last segments accepted
        #: held back for causal order: (kind, payload or byte count, frame, ts, the other side's
        #: sequence number to wait for, this direction's sequence number after it)
        self.pending: deque[tuple[int, Any, int, float, int | None, int]] = deque()
        self.pending_bytes = 0
        self.emitted: int | None = None  # handed on up to here (``next`` unless something is held back)
        self.last_no = 0  # frame of the last segment accepted (or SYN)
        self.midstart = False  # the first bytes seen did not follow a SYN
        self.seen = False  # any segment of this direction seen

    def acked_hole(self) -> bool:
        """The other side acknowledged bytes of this direction the capture has not shown."""
        return self.acked is not None and self.next is not None and _behind(self.next, self.acked)

    def has_hole(self) -> bool:
        return bool(self.ooo) or self.acked_hole()


class TcpStream:
    def __init__(self, sink: Any, feed: list[Any]) -> None:
        self.sink = sink
        self.feed = feed  # feed[d](payload, frame, ts)
        self.dirs = (Direction(), Direction())
        self.packets = 0
        self.client: int | None = None  # the direction whose SYN opened the connection
        self.done = False  # reset, or both sides closed
        self.reset_by: int | None = None
        self._holes = False

    # -- input -------------------------------------------------------------------------------
    def segment(self, d: int, seq: int, ack: int, flags: int, payload: bytes, missing: int, no: int,
                ts: float) -> str | None:
        me = self.dirs[d]
        if not flags & 0x07 and seq == me.next and not missing and not self._holes and not me.pending:
            other = self.dirs[d ^ 1]
            onext = other.next
            if not other.pending and (onext is None or not flags & ACK or not 0 < ((ack - onext) & MASK) < HALF):
                self.packets += 1  # in order, nothing missing, nothing held: hand the bytes on
                if payload:
                    me.next = me.emitted = (seq + len(payload)) & MASK
                    me.last_no = no
                    me.recent.append((seq, payload))
                    self.feed[d](payload, no, ts)
                return None
        result = self._segment(d, seq, ack, flags, payload, missing, no, ts)
        return DONE if result is None and self.done else result

    def _segment(self, d: int, seq: int, ack: int, flags: int, payload: bytes, missing: int, no: int,
                 ts: float) -> str | None:
        self.packets += 1
        me, other = self.dirs[d], self.dirs[d ^ 1]
        me.seen = True
        if flags & SYN:
            if self.done:
                return RESTART
            if me.isn is not None:
                if seq == me.isn:
                    return None  # a retransmitted SYN
                if me.closed or other.closed or me.recent:
                    return RESTART
            me.isn = seq
            me.next = me.emitted = (seq + 1) & MASK
            me.last_no = no
            seq = me.next
            if not flags & ACK:
                self.client = d
            elif self.client is None:
                self.client = d ^ 1
        elif self.done:
            return None
        if flags & RST:
            self._flush_holes(ts)
            self.done = self._holes = True  # _holes: every later packet takes the long path
            self.reset_by = d
            self.sink.close(d, "rst", no, ts)
            return None
        got_ack = ack if flags & ACK else None
        if got_ack is not None and other.next is not None and _behind(other.next, ack) and \
                (other.acked is None or _behind(other.acked, ack)):
            other.acked = ack
            if other.hole_pkt is None:
                other.hole_pkt, other.hole_ts, other.hole_no = self.packets, ts, no
            self._holes = True
        if payload or missing or flags & FIN:
            self._data(d, seq, payload, missing, bool(flags & FIN), no, ts, got_ack)
        if self._holes:
            self._check_holes(ts)
        return None

    def _data(self, d: int, seq: int, payload: bytes, missing: int, fin: bool, no: int, ts: float,
              got_ack: int | None) -> None:
        """Bytes (or a FIN) at ``seq``: in order, old (compared, the rest kept) or ahead (held)."""
        me = self.dirs[d]
        if me.next is None:
            me.next = me.emitted = seq
            me.midstart = True
            self.sink.midstart(d)
        off = (seq - me.next) & MASK
        if off == 0:
            if not me.closed:
                if payload or missing:
                    self._accept(d, payload, missing, no, ts, got_ack)
                if fin:
                    self._fin(d, no, ts, got_ack)
                if me.ooo:
                    self._drain(d)
        elif off >= HALF:
            self._old(d, MASK + 1 - off, payload, missing, fin, no, ts, got_ack)
        elif not me.closed:
            if seq not in me.ooo or len(me.ooo[seq][0]) < len(payload):
                me.ooo[seq] = (payload, missing, no, ts, fin, got_ack)
                me.ooo_bytes += len(payload)
            if me.hole_pkt is None:
                me.hole_pkt, me.hole_ts, me.hole_no = self.packets, ts, no
            self._holes = True

    def finish(self, ts: float) -> None:
        """The capture ended: what is still missing is a gap; release everything held."""
        self._flush_holes(ts)

    # -- delivery ---------------------------------------------------------------------------------
    def _emit(self, d: int, kind: int, value: Any, no: int, ts: float, end: int) -> None:
        me = self.dirs[d]
        me.emitted = end
        if kind == _DATA:
            self.feed[d](value, no, ts)
        elif kind == _GAP:
            self.sink.gap(d, value, no, no, ts)
        elif kind == _SNAP:
            self.sink.snap(d, value, no, ts)
        else:
            self.sink.close(d, "fin", no, ts)
            other = self.dirs[d ^ 1]
            if other.closed and not other.pending:
                self.done = self._holes = True
        if self.dirs[d ^ 1].pending:
            self._release(d ^ 1)

    def _deliver(self, d: int, kind: int, value: Any, no: int, ts: float, ack: int | None, end: int) -> None:
        """Hand on now, or hold back while the segment acknowledges bytes of the other side
        that are not handed on yet (or something of this side is held back already)."""
        me, other = self.dirs[d], self.dirs[d ^ 1]
        wait = ack if ack is not None and other.emitted is not None and _behind(other.emitted, ack) else None
        if wait is None and not me.pending:
            self._emit(d, kind, value, no, ts, end)
            return
        if wait is None:
            wait = me.pending[-1][4]
        me.pending.append((kind, value, no, ts, wait, end))
        if kind == _DATA:
            me.pending_bytes += len(value)
            if me.pending_bytes > PENDING_LIMIT or len(me.pending) > 4096:
                self._declare_gap(d ^ 1, ts)
                if me.pending:  # still held: the other side is not missing anything; let go
                    self._release(d, force=True)

    def _accept(self, d: int, payload: bytes, missing: int, no: int, ts: float, ack: int | None) -> None:
        me = self.dirs[d]
        start = me.next
        assert start is not None  # a direction accepts bytes once its start is known
        me.next = (start + len(payload) + missing) & MASK
        me.last_no = no
        if payload:
            me.recent.append((start, payload))
            self._deliver(d, _DATA, payload, no, ts, ack, (start + len(payload)) & MASK)
        if missing:  # cut by the snap length: a count at a known place (``snap``), not a gap
            self._deliver(d, _SNAP, missing, no, ts, ack, me.next)

    def _fin(self, d: int, no: int, ts: float, ack: int | None) -> None:
        me = self.dirs[d]
        if me.closed:
            return
        me.closed = True
        assert me.next is not None
        me.next = (me.next + 1) & MASK
        self._deliver(d, _FIN, None, no, ts, ack, me.next)

    def _drain(self, d: int) -> None:
        me = self.dirs[d]
        while me.ooo and not me.closed:
            nxt = me.next
            assert nxt is not None  # out-of-order bytes wait behind a known start
            best = None
            for s in me.ooo:
                if not _behind(nxt, s):
                    best = s
                    break
            if best is None:
                break
            payload, missing, no, ts, fin, ack = me.ooo.pop(best)
            me.ooo_bytes -= len(payload)
            back = (nxt - best) & MASK
            if back:
                self._old(d, back, payload, missing, fin, no, ts, ack)
                continue
            if payload or missing:
                self._accept(d, payload, missing, no, ts, ack)
            if fin:
                self._fin(d, no, ts, ack)
        if not me.has_hole():
            me.hole_pkt = None

    def _old(self, d: int, back: int, payload: bytes, missing: int, fin: bool, no: int, ts: float,
             ack: int | None) -> None:
        """A segment starting ``back`` bytes before ``next``: compare what is known, keep the rest."""
        me = self.dirs[d]
        size = len(payload)
        nxt = me.next
        assert nxt is not None
        start = (nxt - back) & MASK
        for s0, p0 in me.recent:  # positions relative to ``next``, shifted to stay positive
            a0 = (s0 - nxt + HALF) & MASK
            a = (start - nxt + HALF) & MASK
            lo, hi = max(a, a0), min(a + min(size, back), a0 + len(p0))
            if lo < hi and payload[lo - a : hi - a] != p0[lo - a0 : hi - a0]:
                self.sink.conflict(d, no, ts)
                break
        if back < size + missing and not me.closed:
            self._accept(d, payload[back:], missing - max(0, back - size), no, ts, ack)
            if fin:
                self._fin(d, no, ts, ack)
            if me.ooo:
                self._drain(d)
        elif fin and not me.closed and back == size + missing:
            self._fin(d, no, ts, ack)

    def _release(self, d: int, force: bool = False) -> None:
        """Hand on what direction ``d`` held back, as far as the other side has been handed on."""
        me, other = self.dirs[d], self.dirs[d ^ 1]
        pending = me.pending
        while pending:
            kind, value, no, ts, wait, end = pending[0]
            # wait, unless both sides wait for each other (acknowledgements the capture contradicts):
            # then the earlier frame goes first
            if not force and other.emitted is not None and wait is not None and _behind(other.emitted, wait) \
                    and not (other.pending and other.pending[0][4] is not None and me.emitted is not None
                             and _behind(me.emitted, other.pending[0][4]) and no < other.pending[0][2]):
                return
            pending.popleft()
            if kind == _DATA:
                me.pending_bytes -= len(value)
            self._emit(d, kind, value, no, ts, end)

    # -- holes ------------------------------------------------------------------------------------
    def _check_holes(self, ts: float) -> None:
        for d in (0, 1):
            me = self.dirs[d]
            if me.hole_pkt is None:
                continue
            if not me.has_hole():
                me.hole_pkt = None
                continue
            age = self.packets - me.hole_pkt
            if (me.acked_hole() and (age >= REORDER_PACKETS or ts - me.hole_ts >= REORDER_S)) \
                    or age >= STALL_PACKETS or me.ooo_bytes > OOO_LIMIT:
                self._declare_gap(d, ts)
        self._holes = self.done or any(x.hole_pkt is not None for x in self.dirs)

    def _declare_gap(self, d: int, ts: float) -> None:
        """The bytes between ``next`` and the first waiting segment (or the other side's ACK) are missing."""
        me = self.dirs[d]
        nxt = me.next
        if nxt is None:
            return
        end, after, best = None, me.hole_no, None
        for s, item in me.ooo.items():
            off = (s - nxt) & MASK
            if off < HALF and (best is None or off < best):
                best, end, after = off, s, item[2]
        if end is None:
            if me.acked is None or not me.acked_hole():
                me.hole_pkt = None
                return
            end = me.acked
        nbytes = (end - nxt) & MASK
        before = me.last_no
        me.next = end
        me.recent.clear()
        me.hole_pkt = None
        if nbytes:
            if me.pending:
                me.pending.append((_GAP, nbytes, before, ts, me.pending[-1][4], end))
            else:
                me.emitted = end
                self.sink.gap(d, nbytes, before, after, ts)
                if self.dirs[d ^ 1].pending:
                    self._release(d ^ 1)
        self._drain(d)
        if me.has_hole():  # more missing after what was waiting: due at once
            me.hole_pkt, me.hole_ts = self.packets - REORDER_PACKETS, ts - REORDER_S
            self._holes = True

    def _flush_holes(self, ts: float) -> None:
        for _ in range(1000):
            busy = False
            for d in (0, 1):
                me = self.dirs[d]
                if me.next is not None and me.has_hole():
                    self._declare_gap(d, ts)
                    busy = True
            if not busy:
                break
        for d in (0, 1):  # the other side will show nothing more: let go of everything held
            if self.dirs[d].pending:
                self._release(d, force=True)

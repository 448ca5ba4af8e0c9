"""Observation iSight conversations in a capture and following each TCP connection.

:class:`Conversations` sorts every TCP segment and UDP datagram by its addresses and
ports. A conversation is iSight when one side is on one of the configured ports (9004
by default, ``--port``), or, with the heuristic on, when one of its first payloads
holds a plausible iSight header (start word, version, transfer type, known action: the
Wireshark dissector's heuristic, a little stricter). Everything else is ignored.

Who is the robot: the side that sent the SYN; without a handshake in the capture, the
side that is not on the iSight port; on an unconfigured port, the side whose frames
carry transfer type 01.

:class:`TcpConversation` chains reassembly (:mod:`.reassembly`), framing (:mod:`.framing`)
and the judgement (:mod:`.exchanges`), and when it ends hands a summary to the
session tracker (:mod:`.sessions`).
"""

from __future__ import annotations

from typing import Any

from ..harness.transcript import Endpoint, Transcript
from ..model.verdicts import Verdict
from ..observed.connections import BY_BOX, BY_ROBOT, BY_ROBOT_RESET, ConnRecord
from ..protocol import TransferType, peek_transfer_type
from .analysis_context import Context
from .capture_packets import ACK, SYN, endpoints, format_endpoint, reverse_key
from .exchanges import ConnJudge
from .findings import BOX, ROBOT
from .framing import FrameReader, plausible_header
from .reassembly import RESTART, TcpStream
from .sessions import ConnOutcome, SessionTracker
from .udp_conversation import UdpConversation

__all__ = ["Conversations", "TcpConversation"]

CANDIDATE_PACKETS = 16  # packets of an undecided conversation kept while its content is looked at
CANDIDATE_BYTES = 16384  # ... and their payload bytes
CANDIDATE_PAYLOADS = 8  # payloads looked at before a conversation on another port is ignored
MAX_CANDIDATES = 2048
MAX_UDP = 20000  # UDP conversations followed at once; past it the one seen first ends
MAX_IGNORED = 200_000
MAX_OPEN = 20000  # connections followed at once; past it the one opened longest ago ends
STRAY_S = 60.0  # packets of a closed connection within this time are its stragglers


class TcpConversation:
    """One TCP connection of an iSight conversation."""

    def __init__(self, ctx: Context, key: bytes, robot_dir: int, ts: float, frame: int, handshake: bool) -> None:
        self.ctx = ctx
        self.key = key
        self.robot_dir = robot_dir
        self.number = ctx.label()
        a, b = endpoints(key)
        robot, box = (a, b) if robot_dir == 0 else (b, a)
        self.robot, self.box = robot, box
        self.label = f"conn {self.number} ({format_endpoint(*robot)} → {format_endpoint(*box)})"
        self.judge = ConnJudge(ctx, self.label, "tcp", midstart=not handshake, box=box, robot=robot)
        robot_reader = FrameReader(ctx.judged, TransferType.ROBOT_TO_BOX, self.judge.request)
        box_reader = FrameReader(ctx.judged, TransferType.BOX_TO_ROBOT, self.judge.answer)
        self.readers = [robot_reader, box_reader] if robot_dir == 0 else [box_reader, robot_reader]
        self.stream = TcpStream(self, [r.feed for r in self.readers])
        self.t_open = ts
        self.handshake = handshake
        self.closes: dict[str, tuple[str, int, float]] = {}
        self.first_close: str | None = None
        self.gap_t: float | None = None
        self.session: Any = None
        self.open_frame = frame
        ctx.stats.tcp_connections += 1
        ctx.stats.robots.add(robot[0])
        ctx.stats.boxes.add(format_endpoint(*box))
        if not handshake:
            ctx.stats.midstart += 1

    def side(self, d: int) -> str:
        return ROBOT if d == self.robot_dir else BOX

    # -- the reassembly's sink ----------------------------------------------------------------------
    def midstart(self, d: int) -> None:
        """Direction ``d``'s first bytes did not follow its SYN: they may start inside a frame."""
        self.readers[d].mark_midstart()

    def gap(self, d: int, nbytes: int, before: int, after: int, ts: float) -> None:
        stats = self.ctx.stats
        stats.gaps += 1
        stats.gap_bytes += nbytes
        if self.gap_t is None:
            self.gap_t = ts
        self.ctx.now = ts
        self.readers[d].gap(nbytes)
        self.judge.gap(self.side(d), before, after)

    def snap(self, d: int, nbytes: int, no: int, ts: float) -> None:
        """``nbytes`` of packet ``no`` cut by the capture's snap length: the reader frames past them, or (when
        the frame they cut does not tell where it ends) they are a gap."""
        self.ctx.now = ts
        if not self.readers[d].snap(nbytes, no, ts):
            stats = self.ctx.stats
            stats.gaps += 1
            stats.gap_bytes += nbytes
            if self.gap_t is None:
                self.gap_t = ts
            self.judge.gap(self.side(d), no, no)

    def close(self, d: int, how: str, no: int, ts: float) -> None:
        side = self.side(d)
        if side not in self.closes:
            self.closes[side] = (how, no, ts)
            if self.first_close is None:
                self.first_close = side
        if how == "fin":
            self.readers[d].close(no, ts)
        else:
            self.readers[d].end()
            self.readers[d ^ 1].end()

    def conflict(self, d: int, no: int, ts: float) -> None:
        self.ctx.stats.conflicts += 1
        if self.ctx.stats.conflicts <= 20:
            self.ctx.findings.tally("F5", self.side(d)).note(
                f"frame {no}: a retransmission on {self.label} carries bytes that differ from the original "
                "(the first copy was judged)")

    # -- the end ------------------------------------------------------------------------------------
    def finish(self, t_end: float, frame_end: int) -> ConnOutcome:
        self.stream.finish(t_end)
        for reader in self.readers:
            reader.end()
            self.ctx.stats.cut_frames += reader.cut
            self.ctx.stats.skipped_bytes += reader.skipped
        closes, judge = self.closes, self.judge
        robot_close, box_close = closes.get(ROBOT), closes.get(BOX)
        if box_close is not None and self.first_close == BOX:
            end = "box"
        elif robot_close is not None and robot_close[0] == "rst":
            end = "robot-reset"
        elif robot_close is not None and box_close is not None:
            end = "robot"
        else:
            end = "capture"
        judge.finish(end, t_end, box_close[2] if box_close else None, box_close[1] if box_close else frame_end)
        self._s5(robot_close, box_close, t_end)
        if end == "capture":
            self.ctx.stats.open_at_end += 1
        closed_by = None
        if self.first_close == ROBOT and robot_close is not None:
            closed_by = BY_ROBOT if robot_close[0] == "fin" else BY_ROBOT_RESET
        elif self.first_close == BOX:
            closed_by = BY_BOX
        first = closes.get(self.first_close) if self.first_close else None
        record = ConnRecord(0, "tcp", Transcript(), Endpoint(*self.box), Endpoint(*self.robot), self.t_open,
                            first[2] if first else None, closed_by,
                            f"{'reset' if first and first[0] == 'rst' else 'closed'} by the {self.first_close}"
                            if first else "open when the capture ends", list(judge.actions), judge.exchanges)
        frame_at = dict(judge.frame_at)
        frame_at.setdefault(self.t_open, self.open_frame)
        if first is not None:
            frame_at.setdefault(first[2], first[1])
        return ConnOutcome(record, judge.records, judge.first_pose, judge.pose_after, self.handshake, self.gap_t,
                           list(judge.refusals), frame_at, self.label, end == "capture", t_end,
                           judge.clock.finish(), self.number)

    def _s5(self, robot_close: tuple[str, int, float] | None, box_close: tuple[str, int, float] | None,
            t_end: float) -> None:
        if robot_close is None or robot_close[0] != "fin" or self.first_close != ROBOT:
            return
        f = self.ctx.findings
        if box_close is not None:
            f.check("S5", BOX)
        elif t_end - robot_close[2] >= self.ctx.time_out_s:
            f.add("S5", BOX, Verdict.FAIL, f"{self.label}: the robot closed (FIN) and the box had not closed its "
                  f"side {t_end - robot_close[2]:.1f} s later, when the capture ends", (robot_close[1],))
        else:
            f.add("S5", BOX, Verdict.INCONCLUSIVE, f"{self.label}: the capture ends {t_end - robot_close[2]:.3f} s "
                  "after the robot's FIN, before the box closed its side", (robot_close[1],))


class _Candidate:
    __slots__ = ("key", "packets", "payloads", "robot_dir", "size")

    def __init__(self, key: bytes) -> None:
        self.key = key  # the first packet's direction
        self.packets: list[tuple[Any, ...]] = []
        self.payloads = 0
        self.robot_dir: int | None = None
        self.size = 0


class Conversations:
    """Every conversation of the capture: iSight ones followed, the rest ignored."""

    def __init__(self, ctx: Context, sessions: SessionTracker) -> None:
        self.ctx = ctx
        self.sessions = sessions
        self.ports = frozenset(ctx.config.ports)
        self.heuristic = ctx.config.heuristic
        #: both directions' keys -> (the connection's ``segment``, direction, connection)
        self.tcp: dict[bytes, tuple[Any, int, TcpConversation]] = {}
        self.udp: dict[bytes, tuple[UdpConversation, int]] = {}
        self.open: dict[int, TcpConversation] = {}
        self.candidates: dict[bytes, _Candidate] = {}
        self.ignored: dict[bytes, None] = {}
        self.closed: dict[bytes, float] = {}
        self.profile = ctx.profile

    # -- TCP ------------------------------------------------------------------------------------------
    def tcp_packet(self, key: bytes, seq: int, ack: int, flags: int, payload: bytes, missing: int, no: int,
                   ts: float) -> None:
        entry = self.tcp.get(key)
        if entry is not None:
            result = entry[0](entry[1], seq, ack, flags, payload, missing, no, ts)
            if result is not None:
                self.settle(entry[2], result, key, seq, ack, flags, payload, missing, no, ts)
            return
        if key in self.ignored:
            return
        closed_at = self.closed.get(key)
        if closed_at is not None and not flags & SYN and ts - closed_at < STRAY_S:
            return
        packet = (key, seq, ack, flags, payload, missing, no, ts)
        sport, dport = (key[-4] << 8) | key[-3], (key[-2] << 8) | key[-1]
        if sport in self.ports or dport in self.ports:
            if flags & SYN:
                robot_dir = 0 if not flags & ACK else 1
            elif dport in self.ports and sport not in self.ports:
                robot_dir = 0
            elif sport in self.ports and dport not in self.ports:
                robot_dir = 1
            else:
                pos = plausible_header(payload, 0, None, self.profile) if payload else -1
                robot_dir = 1 if pos >= 0 and peek_transfer_type(payload, pos) == TransferType.BOX_TO_ROBOT else 0
            self._start(key, robot_dir, [packet], bool(flags & SYN))
            return
        if not self.heuristic:
            self._ignore(key)
            return
        self._candidate(key, packet)

    def settle(self, conn: TcpConversation, result: str, key: bytes, seq: int, ack: int, flags: int, payload: bytes,
               missing: int, no: int, ts: float) -> None:
        """After ``segment`` returned DONE (the connection ended) or RESTART (a SYN reuses its ports)."""
        self._retire(conn, ts, no)
        if result is RESTART:
            self._start(key, 0 if not flags & ACK else 1, [(key, seq, ack, flags, payload, missing, no, ts)], True)

    def _candidate(self, key: bytes, packet: tuple[Any, ...]) -> None:
        rev = reverse_key(key)
        canon = min(key, rev)
        cand = self.candidates.get(canon)
        if cand is None:
            if len(self.candidates) >= MAX_CANDIDATES:
                oldest = next(iter(self.candidates))
                del self.candidates[oldest]
            cand = self.candidates[canon] = _Candidate(key)
        flags, payload = packet[3], packet[4]
        d = 0 if key == cand.key else 1
        if flags & SYN:
            cand.robot_dir = d if not flags & ACK else d ^ 1
        cand.packets.append(packet)
        cand.size += len(payload)
        if payload:
            cand.payloads += 1
            pos = plausible_header(payload, 0, None, self.profile)
            if pos >= 0:
                del self.candidates[canon]
                robot_dir = cand.robot_dir
                if robot_dir is None:
                    robot_dir = d if peek_transfer_type(payload, pos) == TransferType.ROBOT_TO_BOX else d ^ 1
                self._start(cand.key, robot_dir, cand.packets, bool(cand.packets[0][3] & SYN))
                return
        if cand.payloads >= CANDIDATE_PAYLOADS or len(cand.packets) >= CANDIDATE_PACKETS or cand.size > CANDIDATE_BYTES:
            del self.candidates[canon]
            self._ignore(key)
            self._ignore(rev)

    def _ignore(self, key: bytes) -> None:
        if len(self.ignored) >= MAX_IGNORED:
            self.ignored.clear()
        self.ignored[key] = None

    def _start(self, key: bytes, robot_dir: int, packets: list[tuple[Any, ...]], handshake: bool) -> None:
        """A new connection; ``packets`` (its first ones, ``key``'s direction first) are fed to it."""
        ctx = self.ctx
        conn = TcpConversation(ctx, key, robot_dir, packets[0][7], packets[0][6], handshake)
        self.tcp[key] = (conn.stream.segment, 0, conn)
        self.tcp[reverse_key(key)] = (conn.stream.segment, 1, conn)
        self.open[conn.number] = conn
        conn.session = self.sessions.attach(conn)
        if len(self.open) > MAX_OPEN:  # the connection opened longest ago ends (as if the capture ended)
            self._retire(next(iter(self.open.values())), ctx.now, ctx.frame)
        for packet in packets:
            self.tcp_packet(*packet)

    def _retire(self, conn: TcpConversation, ts: float, no: int) -> None:
        rev = reverse_key(conn.key)
        for k in (conn.key, rev):
            if self.tcp.get(k, (None, 0, None))[2] is conn:
                del self.tcp[k]
            self.closed[k] = ts
        if len(self.closed) > 4096:
            self.closed = {k: t for k, t in self.closed.items() if ts - t < STRAY_S}
        self.open.pop(conn.number, None)
        self.sessions.done(conn, conn.finish(ts, no))
        conn.stream.sink = None  # no reference cycle: the connection is freed now, not at a later GC pass

    # -- UDP ------------------------------------------------------------------------------------------
    def udp_packet(self, key: bytes, payload: bytes, missing: int, no: int, ts: float) -> None:
        entry = self.udp.get(key)
        if entry is None:
            if key in self.ignored:
                return
            sport, dport = (key[-4] << 8) | key[-3], (key[-2] << 8) | key[-1]
            pos = plausible_header(payload, 0, None, self.profile) if payload else -1
            if dport in self.ports and sport not in self.ports:
                robot_dir = 0
            elif sport in self.ports and dport not in self.ports:
                robot_dir = 1
            elif pos == 0 and (sport in self.ports or dport in self.ports or self.heuristic):
                robot_dir = 0 if peek_transfer_type(payload) == TransferType.ROBOT_TO_BOX else 1
            else:
                self._ignore(key)
                return
            conv = UdpConversation(self.ctx, key, robot_dir)
            if len(self.udp) >= 2 * MAX_UDP:  # the conversation seen first ends, as if the capture ended there
                oldest = next(iter(self.udp.values()))[0]
                oldest.finish(ts)
                for k in [k for k, (c, _d) in self.udp.items() if c is oldest]:
                    del self.udp[k]
            self.udp[key] = (conv, 0)
            self.udp[reverse_key(key)] = (conv, 1)
            entry = (conv, 0)
        conv, d = entry
        conv.datagram(d, payload, missing, no, ts)

    # -- the end ----------------------------------------------------------------------------------------
    def finish(self, ts: float, no: int) -> None:
        for conn in list(self.open.values()):
            self._retire(conn, ts, no)
        for conv in {c for c, _ in self.udp.values()}:
            conv.finish(ts)
        self.udp.clear()
        self.candidates.clear()

"""One connection's requests and answers, paired as they come (sans-I/O).

:class:`ConnJudge` gets the robot's events (:meth:`request`) and the box's
(:meth:`answer`) in causal order, each a codec :class:`~conformance.protocol.Frame`
or :class:`~conformance.protocol.ProtocolError` with its bytes and frame numbers, and:

* files every frame error of both sides under its clause (the codec names it);
* pairs each answer with its request, in order (A1), checks the action is echoed (A2)
  and the latency against time_out (T1; vision_time_out for 27, E5), and has
  :mod:`.judging` judge the answer's content with the protocol's facts about answers.
  A malformed request may legally go unanswered; an answer is paired with such a
  request only when no legal pairing explains it otherwise (R6's rule: "judge 0000 to
  malformed input only when no legal framing explains the 0000");
* keeps what the session needs (the non-pose requests and their answers, the first
  poses, the box's refusals) and the pose clock of T2.

After a gap, or when the connection began before the capture, pairing cannot be
trusted: findings that depend on it become INCONCLUSIVE (never FAIL), naming the frames
around the gap. A well-formed pose and its 0000 answer take a short path.
"""

from __future__ import annotations

from array import array
from collections import deque
from typing import Any

from ..harness.starvation import is_loopback
from ..model.verdicts import Verdict, broken_verdict
from ..observed.connections import Exchange
from ..observed.robot_frames import FrameRecord
from ..protocol import EXTENSION_ACTIONS, Action, Frame, ProtocolError, action_name
from ..protocol.answers import Cycle, unanswered
from ..protocol.constants import START_WORD, VERSION
from .analysis_context import Context
from .capture_catalogue import spec_for
from .capture_timing import BLOCK, PoseClock
from .findings import BOX, ROBOT, Series, frames_text
from .judging import (
    BAD_DATAGRAM,
    F4_SAMPLE,
    KIND,
    NOT_REQUEST,
    OK,
    byte_order,
    count_frames,
    expect,
    judge_backlog,
    judge_pair,
)
from .snapcut import SnapCut, note_cut

__all__ = ["ConnJudge", "action_name"]

FAIL, NON_STRICT, INCONCLUSIVE = Verdict.FAIL, Verdict.NON_STRICT, Verdict.INCONCLUSIVE
#: a box frame error's clause, as the box's case it belongs to
_BOX_CLAUSE = {"A5": "A2", "B3": "E1", "B1": "A2", "B2": "A2", "B5": "A2"}
POSE, CYCLE_ON, VISION_RESULT = Action.POSE, Action.CYCLE_ON, Action.VISION_RESULT
KEEP_REQUESTS = 2000  # non-pose requests kept per connection for the session judgement
LATENCY_BATCH = 4096
MAX_OUTSTANDING = 65536  # requests waiting for their answers; past it the box is far behind: pairing stops
SKIPPED_KEEP = 64
_READ = (Frame, SnapCut)


def _header_action(err: ProtocolError) -> int | None:
    h = err.header
    if h is None or h.start_word != START_WORD or h.version != VERSION:
        return None
    return int(h.action)


class ConnJudge:
    """The judgements of one TCP connection (or one UDP conversation, ``transport="udp"``)."""

    def __init__(self, ctx: Context, label: str, transport: str = "tcp", midstart: bool = False,
                 box: Any = None, robot: Any = None) -> None:
        self.ctx = ctx
        self.label = label  # "conn 3 (10.0.0.2:51000 → 10.0.0.1:9004)"
        self.transport = transport
        self.midstart = midstart
        self.box = box  # the box's address, for its cycle state
        self.cycle = Cycle.UNKNOWN if midstart else Cycle.IDLE  # this connection's cycle state, as far as seen
        self.findings = ctx.findings
        #: outstanding requests: (t, action, first frame, last frame, kind, raw, event, exchange, expectation)
        self.queue: deque[tuple[Any, ...]] = deque()
        self.robot_counts: dict[int, int] = {}  # well-formed non-pose requests per action
        self.box_counts: dict[int, int] = {}  # well-formed answers per action (but the short path's poses)
        self.robot_errors = self.box_errors = 0
        self.answer_codes: dict[int, int] = {}  # answers per error code (but the short path's poses: 0000)
        #: the monitor's live histogram of the poses' answer latencies (ms), when it watches (else None)
        self.observe_pose: Any = getattr(ctx, "observe_pose", None)
        self.poses = self.box_poses = 0  # well-formed poses; well-formed pose answers on the short path
        self.paired = self.paired_poses = self.poses_ok = 0
        self.t1_ms = ctx.time_out_s * 1000.0
        self.steady = False  # the short path for poses is open (F4 sampled, no gap)
        self.f4 = {ROBOT: 0, BOX: 0}
        self.seen_request = False
        self.desync: str | None = None  # why pairing stopped (a gap)
        self.not_paired = 0  # requests and answers after the desync
        self.garbage_t: float | None = None  # the robot's first bytes that were not a request
        self.r6_checked = False
        self.skipped: deque[tuple[Any, ...]] = deque(maxlen=SKIPPED_KEEP)  # malformed requests left unanswered
        self.pose_latency = Series(cap=1024)  # the poses' answer latencies (ms), in order
        self._latencies = array("d")  # the latest ones, before they go into pose_latency in a batch
        # a robot on this host (loopback): the host's CPU contention can explain its jitter (harness.starvation)
        self.clock = PoseClock(ctx.profile.pose_rate_hz, ctx.config.rate_tolerance, ctx.config.jitter_tolerance,
                               ctx.intervals, peer_local=robot is not None and is_loopback(str(robot[0])))
        # for the session: requests kept (FrameRecord, Exchange), first poses, refusals
        self.records: list[FrameRecord] = []
        self.exchanges: list[Exchange] = []
        self.actions: list[int] = []  # distinct request actions, in order of first appearance
        self.first_pose: tuple[float, int, int, Any] | None = None  # (t, frame, offset, event)
        self.want_pose_after: float | None = None  # the session's first CycleOn: keep the next pose
        self.pose_after: tuple[float, int, int, Any] | None = None
        self.refusals: list[tuple[float, str]] = []  # (t, why): the box answered non-0000, stayed silent, closed
        self.frame_at: dict[float, int] = {}
        self.on_cycle_on: Any = None  # the session's callback for the first CycleOn

    # -- the robot's events ----------------------------------------------------------------------
    def request(self, event: Any, raw: bytes, offset: int, first: int, last: int, t: float) -> None:
        if type(event) is Frame and event.action is POSE and self.steady and not self.robot_counts:
            # the stream's pose (after the first ones): counted, timed and queued for its answer
            self.poses += 1
            times = self.clock.times
            times.append(t)
            if len(times) >= BLOCK:
                self.clock.flush()
            if self.want_pose_after is not None and self.pose_after is None and t > self.want_pose_after:
                self.pose_after = (t, last, offset, event)
            queue = self.queue
            queue.append((t, POSE, first, last, OK, raw, event, None, None))
            if len(queue) > MAX_OUTSTANDING:
                self._overflow(t)
            return
        self._request(event, raw, offset, first, last, t)

    def _request(self, event: Any, raw: bytes, offset: int, first: int, last: int, t: float) -> None:
        self.seen_request = True
        action: int | None
        exp = None
        if type(event) is SnapCut and note_cut(self, event, (first, last), ROBOT) is None:
            return
        if type(event) in _READ:  # a frame, or one the capture cut: judged on its header
            action = event.action
            if action is POSE:
                self.poses += 1
                self.clock.add(t)
                if self.first_pose is None:
                    self.first_pose = (t, last, offset, event)
                    self._note_action(action)
                if self.want_pose_after is not None and self.pose_after is None and t > self.want_pose_after:
                    self.pose_after = (t, last, offset, event)
                if self.f4[ROBOT] < F4_SAMPLE and type(event) is Frame:
                    byte_order(self, ROBOT, event, raw, offset, t, last)
                else:
                    self.steady = self.desync is None
            else:
                counts = self.robot_counts
                counts[action] = counts.get(action, 0) + 1
                self._note_action(action)
                if self.f4[ROBOT] < F4_SAMPLE and event.blocks:
                    byte_order(self, ROBOT, event, raw, offset, t, last)
            exp = expect(event, self.ctx, self.transport)
        else:
            action = _header_action(event)
            exp = self._robot_error(event, raw, action, first, last, t, offset)
            if action == POSE:
                self.clock.add(t)
        if self.desync is not None:
            self.not_paired += 1
            return
        exchange = None
        if action is POSE and self._keep_pose(t):
            # a pose the session judges (its first, the first in the cycle, one on a command connection):
            # what the box did about it is kept too, so A1/T1 of the robot see its answer
            exchange = Exchange(offset, t, action, "pending")
            self.exchanges.append(exchange)
            if self.robot_counts:
                self.records.append(FrameRecord(0, self.transport, t, offset, raw[:64], event))
            self.frame_at.setdefault(t, last)
        elif action is not None and action is not POSE and len(self.records) < KEEP_REQUESTS:
            exchange = Exchange(offset, t, action, "pending")
            self.records.append(FrameRecord(0, self.transport, t, offset, raw[:64], event))
            self.exchanges.append(exchange)
            self.frame_at.setdefault(t, last)
            if action == CYCLE_ON and self.on_cycle_on is not None:
                self.on_cycle_on(t)
        self.queue.append((t, action, first, last, KIND[exp.rule], raw, event, exchange, exp))
        if len(self.queue) > MAX_OUTSTANDING:
            self._overflow(t)

    def _keep_pose(self, t: float) -> bool:
        """Keep this pose's exchange: the connection's first pose or the first after the cycle began (the
        session's records), or any pose on a connection that carries commands (ISIGHT(3,35)), within bounds."""
        if len(self.exchanges) >= KEEP_REQUESTS:
            return False
        return bool(self.robot_counts) or (self.first_pose is not None and self.first_pose[0] == t) or \
            (self.pose_after is not None and self.pose_after[0] == t)

    def _note_action(self, action: int) -> None:
        if action not in self.actions:
            self.actions.append(action)

    def _robot_error(self, err: ProtocolError, raw: bytes, action: int | None, first: int, last: int, t: float,
                     offset: int) -> Any:
        self.robot_errors += 1
        clause = err.clause
        self.findings.add(clause, ROBOT, broken_verdict(spec_for(clause, ROBOT).level),
                          f"{self.label}, offset {offset}: {err.message}", (first, last), robot=raw)
        if clause in ("F2", "F1") and self.f4[ROBOT] < F4_SAMPLE:
            byte_order(self, ROBOT, err, raw, offset, t, last)
        if action is not None:
            self._note_action(action)
        exp = expect(err, self.ctx, self.transport)
        if KIND[exp.rule] == NOT_REQUEST and self.garbage_t is None:
            self.garbage_t = t
        return exp

    # -- the box's events ---------------------------------------------------------------------------
    def answer(self, event: Any, raw: bytes, offset: int, first: int, last: int, t: float) -> None:
        queue = self.queue
        if type(event) is Frame and event.action is POSE and not event.error_code and queue:
            head = queue[0]
            if head[1] is POSE and head[4] == OK and head[7] is None:  # the stream's answer, 0000, to its pose
                latency = (t - head[0]) * 1000.0
                if latency <= self.t1_ms:
                    queue.popleft()
                    self.box_poses += 1
                    lat = self._latencies
                    lat.append(latency)
                    if self.observe_pose is not None:
                        self.observe_pose(latency)
                    if len(lat) >= LATENCY_BATCH:
                        self.pose_latency.extend(lat)
                        self._latencies = array("d")
                    self.paired += 1
                    self.paired_poses += 1
                    self.poses_ok += 1
                    return
        self._answer(event, raw, offset, first, last, t)

    def _answer(self, event: Any, raw: bytes, offset: int, first: int, last: int, t: float) -> None:
        action: int | None
        code: int | None
        if type(event) is SnapCut:  # a frame the capture cut: paired and timed by its header, its content not judged
            if (action := note_cut(self, event, (first, last), BOX)) is None:
                return
            code = event.error_code
            self.box_counts[action] = self.box_counts.get(action, 0) + 1
        elif type(event) is Frame:
            action = event.action
            code = event.error_code
            self.box_counts[event.action] = self.box_counts.get(event.action, 0) + 1
            self.answer_codes[code] = self.answer_codes.get(code, 0) + 1
            if event.blocks and self.f4[BOX] < F4_SAMPLE and not self._echoes(event):
                byte_order(self, BOX, event, raw, offset, t, last)
        else:
            self.box_errors += 1
            clause = _BOX_CLAUSE.get(event.clause, event.clause)
            self.findings.add(clause, BOX, broken_verdict(spec_for(clause, BOX).level),
                              f"{self.label}, offset {offset}: {event.message}", (first, last), box=raw)
            # the robot may take a malformed answer for a refusal and stop: what it does next is not judged
            self.refused(t, f"the box sent a malformed frame ({event.clause})")
            if event.clause in ("F2", "F1") and self.f4[BOX] < F4_SAMPLE:
                byte_order(self, BOX, event, raw, offset, t, last)
            action = _header_action(event)
            if action is None:
                return  # garbage from the box: nothing to pair
            code = event.header.error_code
        if self.desync is not None:
            self.not_paired += 1
            return
        queue = self.queue
        while queue and queue[0][4] != OK:
            head = queue[0]
            if head[1] == action and not (code == 0 and self._ok_later(action)):
                break
            queue.popleft()
            self._unanswered(head, "the box answered a later request instead")
        if not queue:
            self._unsolicited(raw, action, code, first, last)
            return
        self._pair(queue.popleft(), event, raw, action, code, last, t)

    def _echoes(self, event: Frame) -> bool:
        """The answer carries the very blocks of the request it answers (a ProgIdx echoed): their byte order
        is the robot's, not evidence about the box's (F4)."""
        head = self.queue[0] if self.queue else None
        return head is not None and type(head[6]) is Frame and head[6].blocks == event.blocks

    def _ok_later(self, action: int | None) -> bool:
        return any(r[4] == OK and r[1] == action for r in self.queue)

    def _unsolicited(self, raw: bytes, action: int | None, code: int | None, first: int, last: int) -> None:
        if self.midstart and not self.seen_request:
            return  # the answer to a request sent before the capture began
        name = action_name(action)
        for i, req in enumerate(self.skipped):
            if req[1] == action and code == 0:
                del self.skipped[i]
                self.findings.add("R1", BOX, FAIL,
                                  f"{self.label}: {action_name(req[1])} request that breaks {req[6].clause} "
                                  f"({req[6].message}) answered 0000: no legal pairing explains the 0000",
                                  (req[3], last), robot=req[5], box=raw)
                return
        if self.midstart:
            self.findings.add("A1", BOX, INCONCLUSIVE,
                              f"{self.label}: {name} answer with no request in the capture; the connection began "
                              "before the capture, the request may be older", (first, last), box=raw)
            return
        self.findings.add("A1", BOX, FAIL, f"{self.label}: {name} answer with no request left to answer "
                          "(an extra answer)", (first, last), box=raw)

    def _pair(self, req: tuple[Any, ...], event: Any, raw: bytes, action: int | None, code: int | None, last: int,
              t: float) -> None:
        t_req, r_action, _r_first, r_last, kind, r_raw, r_event, exchange, exp = req
        ctx = self.ctx
        latency = (t - t_req) * 1000.0
        self.paired += 1
        if r_action is POSE:
            self.paired_poses += 1
            self._latencies.append(latency)
            if self.observe_pose is not None:
                self.observe_pose(latency)
        else:
            ctx.latency.add(latency)
        frames = (r_last, last)
        bound_s = ctx.vision_time_out_s if r_action == VISION_RESULT else ctx.time_out_s
        limit = bound_s * 1000.0
        if latency > limit:
            self.findings.add("T1", BOX, FAIL, f"{self.label}: {action_name(r_action)} answered after "
                              f"{latency:.1f} ms; the bound is {limit:.0f} ms", frames, robot=r_raw, box=raw)
            # the robot stops waiting at its time_out: from then on it may give the session up
            self.refused(t_req + bound_s, f"the box did not answer {action_name(r_action)} within "
                                                 f"{limit:.0f} ms")
        if exchange is not None:
            exchange.answer, exchange.t_answer, exchange.error_code = raw, t, code
            exchange.reaction = "answered"
            exchange.answer_text = event.describe() if type(event) is Frame else f"[{event.clause}] {event.message}"
            if type(event) is Frame and event.blocks:
                exchange.value = getattr(event.blocks[0], "value", None)
        if r_action is not None and action != r_action and kind != NOT_REQUEST:
            self.findings.add("A2", BOX, FAIL, f"{self.label}: the answer to {action_name(r_action)} carries action "
                              f"{action_name(action)}", frames, robot=r_raw, box=raw)
        if code is not None and type(event) is not SnapCut:
            judge_pair(self, exp, r_action, r_event, event, code, frames, r_raw, raw, t)
        if self.garbage_t is not None and t_req > self.garbage_t and kind == OK and not self.r6_checked:
            self.r6_checked = True
            self.findings.check("R6", BOX)

    def refused(self, t: float, why: str | None) -> None:
        """The box refused something at ``t``: the robot may stop its session there (a cut)."""
        if why and len(self.refusals) < 8:
            self.refusals.append((t, f"{why} on {self.label}"))

    def _unanswered(self, req: tuple[Any, ...], how: str) -> None:
        """A request the box may leave unanswered was left so: only SHOULDs can be missed."""
        kind, action, exp = req[4], req[1], req[8]
        if kind in (NOT_REQUEST, BAD_DATAGRAM) or exp is None:
            self.findings.check("R7" if kind == BAD_DATAGRAM else "R1", BOX)
        else:
            self.skipped.append(req)
            for finding in unanswered(exp, False, how):
                self.findings.add(finding.clause, BOX, NON_STRICT, f"{self.label}: {finding.requirement}; {how}",
                                  (req[3],), robot=req[5])
        if req[7] is not None:
            req[7].reaction = "silent"
            self.refused(req[0], f"the box did not answer {action_name(action)}")

    def _overflow(self, t: float) -> None:
        """More requests wait than any box keeps: report the oldest, stop pairing (bounded memory)."""
        t_req, action, _first, last, _kind, raw = self.queue[0][:6]
        if (t - t_req) * 1000.0 > self.t1_ms:
            self.findings.add("A1", BOX, FAIL, f"{self.label}: {action_name(action)} not answered in "
                              f"{(t - t_req) * 1000:.0f} ms, while {len(self.queue):,} requests wait", (last,),
                              robot=raw)
            self.findings.add("T1", BOX, FAIL, f"{self.label}: no answer to {action_name(action)} within "
                              f"{self.t1_ms:.0f} ms", (last,), robot=raw)
        self.desync = f"more than {MAX_OUTSTANDING:,} requests waited for their answers at once"
        self.not_paired += len(self.queue)
        self.queue.clear()
        self.steady = False

    # -- the end ------------------------------------------------------------------------------------------
    def gap(self, side: str, before: int, after: int) -> None:
        """Bytes of ``side`` are missing between frames ``before`` and ``after``: stop pairing."""
        where = f"the capture lacks {side} bytes between {frames_text((before,))} and {frames_text((after,))}"
        if side == ROBOT:
            self.clock.cut()
        if self.desync is None:
            self.desync = where
            self.not_paired += sum(1 for req in self.queue if req[4] == OK)
            self.queue.clear()
            self.refused(self.ctx.now, f"a gap in the capture ({where})")
        self.steady = False

    def finish(self, end: str, t_end: float, box_closed: float | None, frame_end: int) -> None:
        """``end``: how observation ended: "box" (the box closed or reset first), "robot" (the robot
        closed and the box closed after), "robot-reset", "capture" (still open at the capture's end)."""
        f, label = self.findings, self.label
        for req in self.queue:
            t_req, action, _first, last, kind, raw, _event, exchange, _exp = req
            if kind != OK:
                self._unanswered(req, "no answer followed")
                continue
            limit = self.ctx.vision_time_out_s if action == VISION_RESULT else self.ctx.time_out_s
            waited = (box_closed if box_closed is not None else t_end) - t_req
            if exchange is not None:
                exchange.reaction = "close" if end in ("box", "robot") else "silent"
            name = action_name(action)
            if action in EXTENSION_ACTIONS and not any(self.box_counts.get(a) for a in EXTENSION_ACTIONS):
                # a box without the extension E may stay silent on 26 and 27 (A5, legal table row
                # extension-refusal); nothing here shows this box implements E
                f.add("A1", BOX, INCONCLUSIVE, f"{label}: {name} never answered; a box without the extension E may "
                      "stay silent on it (A5), and no answer to 26 or 27 shows this box implements E", (last,),
                      robot=raw)
                self.refused(t_req, f"the box did not answer {name}")
            elif self.garbage_t is not None and t_req > self.garbage_t:
                f.add("R6", BOX, NON_STRICT, f"{label}: {name} after the robot's garbage never answered; the box "
                      "neither resynchronised nor closed", (last,), robot=raw)
            elif end in ("box", "robot") or waited >= limit:
                after = (f"the box closed the connection {waited * 1000:.0f} ms later ({frames_text((frame_end,))})"
                         if end in ("box", "robot") else f"in the {waited * 1000:.0f} ms the capture shows after it")
                f.add("A1", BOX, FAIL, f"{label}: {name} never answered: {after}", (last,), robot=raw)
                if waited >= limit:
                    f.add("T1", BOX, FAIL, f"{label}: no answer to {name} within {limit * 1000:.0f} ms", (last,),
                          robot=raw)
                self.refused(t_req, f"the box did not answer {name}")
            else:
                why = "the robot reset the connection" if end == "robot-reset" else "the capture ends"
                f.add("A1", BOX, INCONCLUSIVE, f"{label}: {name} not answered yet when {why} "
                      f"{waited * 1000:.0f} ms later", (last,), robot=raw)
        self.queue.clear()
        if self.desync is not None and self.not_paired:
            f.add("A1", BOX, INCONCLUSIVE, f"{label}: {self.not_paired} request(s)/answer(s) not paired: "
                  f"{self.desync}")
            f.add("T1", BOX, INCONCLUSIVE, f"{label}: latency not measured after the gap: {self.desync}")
        f.check("S3", BOX, self.poses_ok)
        self.pose_latency.extend(self._latencies)
        self._latencies = array("d")
        judge_backlog(self)
        f.check("A1", BOX, sum(self.robot_counts.values()) + self.poses)
        f.check("T1", BOX, self.paired)
        f.check("A2", BOX, self.paired)
        count_frames(self)

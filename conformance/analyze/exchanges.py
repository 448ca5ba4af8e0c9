"""One connection's requests and answers, judged as they come (sans-I/O).

:class:`ConnJudge` gets the robot's events (:meth:`request`) and the box's
(:meth:`answer`) in causal order, each a codec :class:`~conformance.protocol.Frame`
or :class:`~conformance.protocol.ProtocolError` with its bytes and frame numbers, and:

* judges every frame of both sides against F, B, A and E (the codec names the clause);
  the robot's frames with certify-robot's reading, the box's with the active suite's;
* pairs each answer with its request, in order (A1), and judges the pair: the action
  echoed (A2), the error code (A3, A4, S2, S3), the extension's values (E2, E3), the
  latency against time_out (T1; vision_time_out for 27, E5), and 0000 to malformed
  input (R1). A request the robot sent malformed may legally go unanswered; an answer
  is paired with such a request only when no legal pairing explains it otherwise (R6's
  rule: "judge 0000 to malformed input only when no legal framing explains the 0000");
* keeps what the session needs (the non-pose requests and their answers, the first
  poses) and the pose clock of T2.

After a gap, or when the connection began before the capture, pairing cannot be
trusted: findings that depend on it become INCONCLUSIVE (never FAIL), naming the frames
around the gap.
"""

from __future__ import annotations

from collections import deque
from typing import Any

from ..certify.records import Exchange
from ..certify.traffic import FrameRecord, byte_order_evidence
from ..endpoints.behaviour import SENDABLE_RESULTS
from ..protocol import ACTION_ERROR, Action, Frame, ProtocolError
from ..protocol.constants import START_WORD, VERSION
from ..suite.verdicts import Verdict
from .catalogue import spec_for
from .context import Context
from .findings import BOX, ROBOT, Series, frames_text
from .timing import BLOCK, PoseClock, backlog

__all__ = ["ConnJudge", "OK", "MALFORMED", "NOT_REQUEST", "SHOULD_REJECT", "TOLERATED", "BAD_DATAGRAM"]

FAIL, NON_STRICT, INCONCLUSIVE, INFO = Verdict.FAIL, Verdict.NON_STRICT, Verdict.INCONCLUSIVE, Verdict.INFORMATIONAL
#: what a robot event is, for judging the box's answer to it
OK, MALFORMED, NOT_REQUEST, SHOULD_REJECT, TOLERATED, BAD_DATAGRAM = range(6)
_KIND_OF_CLAUSE = {"F1": NOT_REQUEST, "F2": NOT_REQUEST, "F3": NOT_REQUEST, "A5": NOT_REQUEST, "F6": TOLERATED,
                   "B4": SHOULD_REJECT}
#: a box frame error's clause, as the box's case it belongs to
_BOX_CLAUSE = {"A5": "A2", "B3": "E1", "B1": "A2", "B2": "A2", "B5": "A2"}
POSE, CYCLE_ON, CYCLE_OFF, PROG_IDX, VISION_RESULT = (Action.POSE, Action.CYCLE_ON, Action.CYCLE_OFF,
                                                       Action.PROG_IDX, Action.VISION_RESULT)
_SENDABLE = frozenset(SENDABLE_RESULTS)
F4_SAMPLE = 16  # frames with values checked for the byte order, per connection and side
KEEP_REQUESTS = 2000  # non-pose requests kept per connection for the session judgement
SKIPPED_KEEP = 64


def action_name(action: int | None) -> str:
    if action is None:
        return "bytes that are not a request"
    try:
        return Action(action).name
    except ValueError:
        return f"0x{action:02X}"


def _header_action(err: ProtocolError) -> int | None:
    h = err.header
    if h is None or h.start_word != START_WORD or h.version != VERSION:
        return None
    return int(h.action)


class ConnJudge:
    """The judgements of one TCP connection (or one UDP conversation, ``transport="udp"``)."""

    def __init__(self, ctx: Context, label: str, transport: str = "tcp", midstart: bool = False) -> None:
        self.ctx = ctx
        self.label = label  # "conn 3 (10.0.0.2:51000 → 10.0.0.1:9004)"
        self.transport = transport
        self.midstart = midstart
        self.findings = ctx.findings
        self.queue: deque[tuple[Any, ...]] = deque()  # (t, action, first, last, kind, raw, event, exchange)
        self.robot_counts: dict[int, int] = {}  # well-formed requests per action
        self.box_counts: dict[int, int] = {}  # well-formed answers per action
        self.robot_errors = 0
        self.box_errors = 0
        self.paired = 0
        self.paired_poses = 0
        self.poses = 0  # well-formed pose requests
        self.box_poses = 0  # well-formed pose answers taken by the short path
        self.steady = False  # the short path for poses is open (F4 sampled, no gap)
        self.t1_ms = ctx.time_out_s * 1000.0
        self.poses_ok = 0  # well-formed poses answered 0000 in time (the fast path)
        self.f4 = {ROBOT: 0, BOX: 0}
        self.seen_request = False
        self.desync: str | None = None  # why pairing stopped (a gap)
        self.not_paired = 0  # requests and answers after the desync
        self.garbage_t: float | None = None  # the robot's first bytes that were not a request
        self.r6_checked = False
        self.skipped: deque[tuple[Any, ...]] = deque(maxlen=SKIPPED_KEEP)  # malformed requests left unanswered
        self.pose_latency = Series(cap=1024)
        self.clock = PoseClock(ctx.profile.pose_rate_hz, ctx.config.rate_tolerance, ctx.config.jitter_tolerance,
                               ctx.intervals)
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
        if type(event) is Frame and event.action is POSE and self.steady:
            # the stream's pose (after the first ones): counted, timed and queued for its answer
            self.poses += 1
            times = self.clock.times
            times.append(t)
            if len(times) >= BLOCK:
                self.clock.flush()
            if self.want_pose_after is not None and self.pose_after is None and t > self.want_pose_after:
                self.pose_after = (t, last, offset, event)
            self.queue.append((t, POSE, first, last, OK, raw, event, None))
            return
        self._request(event, raw, offset, first, last, t)

    def _request(self, event: Any, raw: bytes, offset: int, first: int, last: int, t: float) -> None:
        self.seen_request = True
        action: int | None
        if type(event) is Frame:
            action = event.action
            kind = OK
            if action is POSE:
                self.poses += 1
                self.clock.add(t)
                if self.first_pose is None:
                    self.first_pose = (t, last, offset, event)
                    self._note_action(action)
                if self.want_pose_after is not None and self.pose_after is None and t > self.want_pose_after:
                    self.pose_after = (t, last, offset, event)
                if self.f4[ROBOT] < F4_SAMPLE:
                    self._byte_order(ROBOT, event, raw, offset, t, last)
                else:
                    self.steady = self.desync is None
            else:
                counts = self.robot_counts
                counts[action] = counts.get(action, 0) + 1
                self._note_action(action)
                if self.f4[ROBOT] < F4_SAMPLE and event.blocks:
                    self._byte_order(ROBOT, event, raw, offset, t, last)
        else:
            action = _header_action(event)
            kind = self._robot_error(event, raw, action, first, last, t, offset)
            if action == POSE:
                self.clock.add(t)
        if self.desync is not None:
            self.not_paired += 1
            return
        exchange = None
        if action is not None and action is not POSE and len(self.records) < KEEP_REQUESTS:
            exchange = Exchange(offset, t, action, "pending")
            self.records.append(FrameRecord(0, self.transport, t, offset, raw[:64], event))
            self.exchanges.append(exchange)
            self.frame_at.setdefault(t, last)
            if action == CYCLE_ON and self.on_cycle_on is not None:
                self.on_cycle_on(t)
        self.queue.append((t, action, first, last, kind, raw, event, exchange))

    def _note_action(self, action: int) -> None:
        if action not in self.actions:
            self.actions.append(action)

    def _robot_error(self, err: ProtocolError, raw: bytes, action: int | None, first: int, last: int, t: float,
                     offset: int) -> int:
        self.robot_errors += 1
        clause = err.clause
        spec = spec_for(clause, ROBOT)
        self.findings.add(clause, ROBOT, spec.level.broken_verdict,
                          f"{self.label}, offset {offset}: {err.message}", (first, last), robot=raw)
        if clause in ("F2", "F1") and self.f4[ROBOT] < F4_SAMPLE:
            self._byte_order(ROBOT, err, raw, offset, t, last)
        if action is not None:
            self._note_action(action)
        kind = _KIND_OF_CLAUSE.get(clause)
        if self.transport == "udp" and clause in ("F7", "F5"):
            kind = BAD_DATAGRAM
        elif kind is None:
            kind = MALFORMED if action is not None else NOT_REQUEST
        if kind == NOT_REQUEST and self.garbage_t is None:
            self.garbage_t = t
        return kind

    # -- the box's events ---------------------------------------------------------------------------
    def answer(self, event: Any, raw: bytes, offset: int, first: int, last: int, t: float) -> None:
        queue = self.queue
        if type(event) is Frame and event.action is POSE and not event.error_code and queue:
            head = queue[0]
            if head[1] is POSE and head[4] == OK:  # the stream's answer, 0000, to the pose it answers
                latency = (t - head[0]) * 1000.0
                if latency <= self.t1_ms:
                    queue.popleft()
                    self.box_poses += 1
                    self.pose_latency.add(latency)
                    self.paired += 1
                    self.paired_poses += 1
                    self.poses_ok += 1
                    return
        self._answer(event, raw, offset, first, last, t)

    def _answer(self, event: Any, raw: bytes, offset: int, first: int, last: int, t: float) -> None:
        action: int | None
        if type(event) is Frame:
            action = event.action
            code = event.error_code
            counts = self.box_counts
            counts[event.action] = counts.get(event.action, 0) + 1
            if event.blocks and self.f4[BOX] < F4_SAMPLE:
                self._byte_order(BOX, event, raw, offset, t, last)
        else:
            self.box_errors += 1
            clause = _BOX_CLAUSE.get(event.clause, event.clause)
            self.findings.add(clause, BOX, spec_for(clause, BOX).level.broken_verdict,
                              f"{self.label}, offset {offset}: {event.message}", (first, last), box=raw)
            if event.clause in ("F2", "F1") and self.f4[BOX] < F4_SAMPLE:
                self._byte_order(BOX, event, raw, offset, t, last)
            action = _header_action(event)
            if action is None:
                return  # garbage from the box: nothing to pair
            code = event.header.error_code  # type: ignore[union-attr]
        if self.desync is not None:
            self.not_paired += 1
            return
        queue = self.queue
        while queue and queue[0][4] != OK:
            head = queue[0]
            if head[1] == action and not (code == 0 and self._ok_later(action)):
                break
            queue.popleft()
            self._unanswered_malformed(head, "the box answered a later request instead")
        if not queue:
            self._unsolicited(event, raw, action, code, first, last, t)
            return
        self._pair(queue.popleft(), event, raw, action, code, last, t)

    def _ok_later(self, action: int | None) -> bool:
        return any(r[4] == OK and r[1] == action for r in self.queue)

    def _unsolicited(self, event: Any, raw: bytes, action: int | None, code: int, first: int, last: int,
                     t: float) -> None:
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

    def _pair(self, req: tuple[Any, ...], event: Any, raw: bytes, action: int | None, code: int, last: int,
              t: float) -> None:
        t_req, r_action, r_first, r_last, kind, r_raw, r_event, exchange = req
        ctx = self.ctx
        latency = (t - t_req) * 1000.0
        self.paired += 1
        if r_action is POSE:
            self.paired_poses += 1
            self.pose_latency.add(latency)
            if kind == OK and code == 0 and action is POSE and latency <= ctx.time_out_s * 1000.0:
                self.poses_ok += 1
                return  # the stream's answer: nothing more to judge
        else:
            ctx.latency.add(latency)
        frames = (r_last, last)
        limit = (ctx.vision_time_out_s if r_action == VISION_RESULT else ctx.time_out_s) * 1000.0
        if latency > limit:
            self.findings.add("T1", BOX, FAIL, f"{self.label}: {action_name(r_action)} answered after "
                              f"{latency:.1f} ms; the bound is {limit:.0f} ms", frames, robot=r_raw, box=raw)
        if exchange is not None:
            exchange.answer, exchange.t_answer, exchange.error_code = raw, t, code
            exchange.reaction, exchange.answer_text = "answered", _describe(event)
            if type(event) is Frame and event.blocks and hasattr(event.blocks[0], "value"):
                exchange.value = event.blocks[0].value
        if r_action is not None and action != r_action:
            self.findings.add("A2", BOX, FAIL, f"{self.label}: the answer to {action_name(r_action)} carries action "
                              f"{action_name(action)}", frames, robot=r_raw, box=raw)
        if kind == OK:
            self._judge_answer(r_action, r_event, event, code, frames, r_raw, raw, t)
        elif kind in (MALFORMED, NOT_REQUEST):
            clause = r_event.clause
            if code == 0:
                self.findings.add("R1", BOX, FAIL, f"{self.label}: {action_name(r_action)} that breaks {clause} "
                                  f"({r_event.message}) answered 0000", frames, robot=r_raw, box=raw)
                self._refused(t, None)
            else:
                self.findings.check("R1", BOX)
                want = ACTION_ERROR.get(r_action) if kind == MALFORMED else None  # type: ignore[arg-type]
                if want is not None and code != want:
                    self.findings.add("A3", BOX, NON_STRICT, f"{self.label}: malformed {action_name(r_action)} "
                                      f"({clause}) answered 0x{code:04X}; A3 says 0x{want:04X}", frames,
                                      robot=r_raw, box=raw)
                elif want is not None:
                    self.findings.check("A3", BOX)
                self._refused(t, f"the box answered a malformed {action_name(r_action)} with 0x{code:04X}")
        elif kind == BAD_DATAGRAM:
            if code == 0:
                self.findings.add("R7", BOX, FAIL, f"{self.label}: datagram that breaks {r_event.clause} "
                                  f"({r_event.message}) answered 0000", frames, robot=r_raw, box=raw)
            else:
                self.findings.add("R7", BOX, NON_STRICT, f"{self.label}: datagram that breaks {r_event.clause} "
                                  f"answered 0x{code:04X}; R7 says it SHOULD be dropped silently", frames,
                                  robot=r_raw, box=raw)
        elif kind == SHOULD_REJECT:
            if code == 0:
                self.findings.add("A3", BOX, NON_STRICT, f"{self.label}: {action_name(r_action)} with a non-finite "
                                  "float answered 0000; B4 says it SHOULD be a parse error", frames,
                                  robot=r_raw, box=raw)
            else:
                self.findings.check("A3", BOX)
        if self.garbage_t is not None and t_req > self.garbage_t and kind == OK and not self.r6_checked:
            self.r6_checked = True
            self.findings.check("R6", BOX)

    def _judge_answer(self, r_action: int | None, r_event: Any, event: Any, code: int, frames: tuple[int, int],
                      r_raw: bytes, raw: bytes, t: float) -> None:
        f = self.findings
        label = self.label
        if r_action is POSE or r_action == Action.REGISTER_POSE:
            if code:
                f.add("S3", BOX, FAIL, f"{label}: well-formed {action_name(r_action)} answered 0x{code:04X}; poses "
                      "are answered 0000 in any cycle state", frames, robot=r_raw, box=raw)
                self._refused(t, f"the box answered {action_name(r_action)} with 0x{code:04X}")
            else:
                f.check("S3", BOX)
        elif r_action == CYCLE_ON:
            if code == 0:
                f.check("S2", BOX)
            elif code == 1:
                f.add("S2", BOX, INFO, f"{label}: CycleOn answered 0001 (box not ready): the rest of the session "
                      "is not judged", frames, robot=r_raw, box=raw)
                self._refused(t, "the box answered CycleOn with 0x0001 (not ready, S2)")
            else:
                f.add("S2", BOX, FAIL, f"{label}: CycleOn answered 0x{code:04X}; S2 allows 0000 or 0001", frames,
                      robot=r_raw, box=raw)
                self._refused(t, f"the box answered CycleOn with 0x{code:04X}")
        elif r_action == CYCLE_OFF:
            if code == 2:
                f.add("A3", BOX, INFO, f"{label}: CycleOff answered 0002 (could not close the detection)", frames,
                      robot=r_raw, box=raw)
                self._refused(t, "the box answered CycleOff with 0x0002")
            elif code:
                f.add("A3", BOX, FAIL, f"{label}: CycleOff answered 0x{code:04X}; A3 allows 0000 or 0002", frames,
                      robot=r_raw, box=raw)
                self._refused(t, f"the box answered CycleOff with 0x{code:04X}")
            else:
                f.check("A3", BOX)
        elif r_action == Action.TOLERANCE:
            if code:
                f.add("A3", BOX, FAIL, f"{label}: well-formed TOLERANCE answered 0x{code:04X}", frames,
                      robot=r_raw, box=raw)
                self._refused(t, f"the box answered TOLERANCE with 0x{code:04X}")
            else:
                f.check("A3", BOX)
        elif r_action == Action.NONE:
            f.check("A4", BOX)
        elif r_action == PROG_IDX:
            self._prog_idx(r_event, event, code, frames, r_raw, raw, t)
        elif r_action == VISION_RESULT and type(event) is Frame and event.blocks:
            value = event.blocks[0].value  # type: ignore[union-attr]
            if value in _SENDABLE:
                f.check("E3", BOX)
            else:
                f.add("E3", BOX, FAIL, f"{label}: result request answered {value}, not a ResultCode the box may "
                      "send (1, 2, 10, 20, 202, 400, 409)", frames, robot=r_raw, box=raw)

    def _prog_idx(self, r_event: Any, event: Any, code: int, frames: tuple[int, int], r_raw: bytes, raw: bytes,
                  t: float) -> None:
        sent = r_event.blocks[0].value
        conflict_code = self.ctx.profile.progidx_conflict == "error-code"
        value = getattr(event.blocks[0], "value", None) if type(event) is Frame and event.blocks else None
        if (conflict_code and code == 409) or (value == 409 and not conflict_code):
            self.findings.add("E2", BOX, INFO, f"{self.label}: ProgIdx {sent} answered 409 (resource conflict): the "
                              "rest of the session is not judged", frames, robot=r_raw, box=raw)
            self._refused(t, "the box answered ProgIdx with 409 (E2)")
        elif value == sent and code == 0:
            self.findings.check("E2", BOX)
        elif type(event) is Frame:
            self.findings.add("E2", BOX, FAIL, f"{self.label}: ProgIdx {sent} answered with value {value} and error "
                              f"0x{code:04X}; E2 wants the same index or 409", frames, robot=r_raw, box=raw)

    def _refused(self, t: float, why: str | None) -> None:
        if why and len(self.refusals) < 8:
            self.refusals.append((t, f"{why} on {self.label}"))

    def _unanswered_malformed(self, req: tuple[Any, ...], why: str) -> None:
        kind, action = req[4], req[1]
        if kind == MALFORMED and action in ACTION_ERROR:
            self.skipped.append(req)
            self.findings.add("A3", BOX, NON_STRICT, f"{self.label}: malformed {action_name(action)} "
                              f"({req[6].clause}) not answered ({why}); A3 says it SHOULD be answered "
                              f"0x{ACTION_ERROR[action]:04X}", (req[3],), robot=req[5])
        elif kind in (MALFORMED, NOT_REQUEST):
            self.findings.check("R1", BOX)
        elif kind == BAD_DATAGRAM:
            self.findings.check("R7", BOX)
        if req[7] is not None:
            req[7].reaction = "silent"
            self._refused(req[0], f"the box did not answer {action_name(action)} (A5)")

    # -- byte order (F4) -------------------------------------------------------------------------------
    def _byte_order(self, side: str, event: Any, raw: bytes, offset: int, t: float, last: int) -> None:
        if len(raw) < 14:
            return
        evidence = byte_order_evidence(FrameRecord(0, self.transport, t, offset, raw, event), self.ctx.profile)
        if evidence is None:
            return
        self.f4[side] += 1
        if evidence == "swapped":
            self.f4[side] = F4_SAMPLE  # one is enough
            order = self.ctx.profile.byte_order
            self.findings.add("F4", side, FAIL, f"{self.label}, offset {offset}: the values read as absurd in "
                              f"{order}-endian order but plausible byte-swapped: the {side} writes the other byte "
                              "order", (last,), **{side: raw})
        else:
            self.findings.check("F4", side)

    # -- the end ------------------------------------------------------------------------------------------
    def gap(self, side: str, before: int, after: int) -> None:
        """Bytes of ``side`` are missing between frames ``before`` and ``after``: stop pairing."""
        where = f"the capture lacks {side} bytes between {frames_text((before,))} and {frames_text((after,))}"
        if side == ROBOT:
            self.clock.cut()
        if self.desync is None:
            self.desync = where
            for req in self.queue:
                if req[4] == OK:
                    self.not_paired += 1
            self.queue.clear()
            self._refused(self.ctx.now, f"a gap in the capture ({where})")
        self.steady = False

    def finish(self, end: str, t_end: float, box_closed: float | None, frame_end: int) -> None:
        """``end``: how observation ended: "box" (the box closed or reset first), "robot" (the robot
        closed and the box closed after), "robot-reset", "capture" (still open at the capture's end)."""
        f, label = self.findings, self.label
        for req in self.queue:
            t_req, action, _first, last, kind, raw, event, exchange = req
            if kind != OK:
                self._unanswered_malformed(req, "no answer followed")
                continue
            limit = self.ctx.vision_time_out_s if action == VISION_RESULT else self.ctx.time_out_s
            waited = (box_closed if box_closed is not None else t_end) - t_req
            if exchange is not None:
                exchange.reaction = "close" if end in ("box", "robot") else "silent"
            if self.garbage_t is not None and t_req > self.garbage_t:
                f.add("R6", BOX, NON_STRICT, f"{label}: {action_name(action)} after the robot's garbage never "
                      "answered; the box neither resynchronised nor closed", (last,), robot=raw)
            elif end in ("box", "robot"):
                f.add("A1", BOX, FAIL, f"{label}: {action_name(action)} never answered: the box closed the "
                      f"connection {waited * 1000:.0f} ms later ({frames_text((frame_end,))})", (last,), robot=raw)
                if waited >= limit:
                    f.add("T1", BOX, FAIL, f"{label}: no answer to {action_name(action)} within "
                          f"{limit * 1000:.0f} ms", (last,), robot=raw)
                self._refused(t_req, f"the box did not answer {action_name(action)}")
            elif waited >= limit:
                f.add("A1", BOX, FAIL, f"{label}: {action_name(action)} never answered in the {waited * 1000:.0f} "
                      "ms the capture shows after it", (last,), robot=raw)
                f.add("T1", BOX, FAIL, f"{label}: no answer to {action_name(action)} within {limit * 1000:.0f} ms",
                      (last,), robot=raw)
                self._refused(t_req, f"the box did not answer {action_name(action)}")
            else:
                why = "the robot reset the connection" if end == "robot-reset" else "the capture ends"
                f.add("A1", BOX, INCONCLUSIVE, f"{label}: {action_name(action)} not answered yet when {why} "
                      f"{waited * 1000:.0f} ms later", (last,), robot=raw)
        self.queue.clear()
        if self.desync is not None and self.not_paired:
            f.add("A1", BOX, INCONCLUSIVE, f"{label}: {self.not_paired} request(s)/answer(s) not paired: "
                  f"{self.desync}")
            f.add("T1", BOX, INCONCLUSIVE, f"{label}: latency not measured after the gap: {self.desync}")
        f.check("S3", BOX, self.poses_ok)
        self._backlog()
        f.check("A1", BOX, sum(self.robot_counts.values()) + self.poses)
        f.check("T1", BOX, self.paired)
        f.check("A2", BOX, self.paired)
        self._count_frames()

    def _backlog(self) -> None:
        """T2 (box): on a stream connection (poses only), the answer latency does not grow."""
        if self.actions != [POSE] or self.transport != "tcp":
            return
        series, ctx = self.pose_latency, self.ctx
        if series.n and (ctx.stream_plot is None or series.max > ctx.stream_plot[0]):
            ctx.stream_plot = (series.max, self.label, series)
        b = backlog(self.pose_latency, self.ctx.profile.pose_rate_hz)
        if b is None:
            if self.paired_poses:
                self.findings.add("T2", BOX, INCONCLUSIVE, f"{self.label}: {self.paired_poses} answered pose(s): too "
                                  "few to see a backlog")
            return
        text = (f"{self.label}: last-quarter p50 latency {b.last_p50_ms:.2f} ms, first-quarter p50 "
                f"{b.first_p50_ms:.2f} ms (limit {b.threshold_ms:.2f} ms) over {self.paired_poses:,} poses")
        if b.grows:
            self.findings.add("T2", BOX, FAIL, text + ": the latency grows (a backlog)")
        else:
            self.findings.check("T2", BOX)
            self.findings.tally("T2", BOX).note(text)

    def _count_frames(self) -> None:
        f = self.findings
        rc, bc = dict(self.robot_counts), dict(self.box_counts)
        rc[POSE] = self.poses
        bc[POSE] = bc.get(POSE, 0) + self.box_poses
        n_robot, n_box = sum(rc.values()) + self.robot_errors, sum(bc.values()) + self.box_errors
        tcp = self.transport == "tcp"
        for clause in ("F1", "F2", "F3", "F5", "A5", "B5"):
            f.check(clause, ROBOT, n_robot)
        for clause in ("F1", "F2", "F3", "F5"):
            f.check(clause, BOX, n_box)
        f.check("F6" if tcp else "F7", ROBOT, n_robot)
        f.check("F6" if tcp else "F7", BOX, n_box)
        poses = rc.get(POSE, 0) + rc.get(Action.REGISTER_POSE, 0)
        f.check("B1", ROBOT, poses)
        f.check("B2", ROBOT, rc.get(Action.TOLERANCE, 0))
        f.check("B3", ROBOT, poses + rc.get(Action.TOLERANCE, 0) + rc.get(PROG_IDX, 0))
        f.check("B4", ROBOT, poses + rc.get(Action.TOLERANCE, 0))
        f.check("E1", ROBOT, rc.get(PROG_IDX, 0))
        f.check("E2", ROBOT, rc.get(PROG_IDX, 0))
        f.check("E3", ROBOT, rc.get(VISION_RESULT, 0))
        f.check("E1", BOX, bc.get(PROG_IDX, 0) + bc.get(VISION_RESULT, 0))


def _describe(event: Any) -> str:
    if type(event) is Frame:
        return event.describe()
    return f"[{event.clause}] {event.message}"

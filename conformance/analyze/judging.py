"""What one exchange shows, filed under the observed cases (sans-I/O).

The protocol's facts about answers live in :mod:`conformance.protocol.answers` (what a
box may answer to each event, as the reference box, the fuzz oracle and the cases read
them): :func:`expect` asks it what the box may do with a robot event, and
:func:`judge_pair` asks it what is wrong with the answer, then files each finding under
the case a reader looks for: a wrong code to a pose is S3, to CycleOn S2, to NONE A4,
to another request A3; 0000 to malformed input is R1 (R7 for a UDP datagram); E2, E3,
B4 and F6 keep their clause. The box's cycle state decides what CycleOn and CycleOff may
be answered (S2, S3); the capture knows it only from what it showed (:class:`Cycles`):
at the capture's start it is unknown, and then any answer is allowed (a MAY), recorded
as INFORMATIONAL.

The rest of a connection's bookkeeping that is not pairing also lives here: the byte
order (F4), the counts of frames judged per clause, the box's backlog (T2).
"""

from __future__ import annotations

from typing import Any

from ..model.verdicts import Level, Verdict, broken_verdict
from ..observed.robot_frames import FrameRecord, byte_order_evidence
from ..protocol import Action, Frame, Transport, action_name
from ..protocol.answers import (
    Expectation,
    Rule,
    Seen,
    allowed_codes,
    judge_answer,
    rule_for_error,
    rule_for_frame,
)
from ..protocol.session_table import CYCLE_ACTIONS, Cycle, cycle_after
from .capture_timing import backlog
from .findings import BOX, ROBOT
from .snapcut import SnapCut, cut_counts, snap_expectation

#: ``j`` below is the connection's :class:`~.exchanges.ConnJudge` (not imported: no import circle)
ConnJudge = Any

__all__ = ["Cycles", "KIND", "byte_order", "count_frames", "expect", "judge_backlog", "judge_pair", "unanswered_case"]

OK, MALFORMED, NOT_REQUEST, SHOULD_REJECT, TOLERATED, BAD_DATAGRAM = range(6)
#: how the pairing treats an event the box may do this with
KIND = {Rule.ANSWER: OK, Rule.ANSWER_SHOULD: TOLERATED, Rule.REJECT: MALFORMED, Rule.REJECT_SHOULD: SHOULD_REJECT,
        Rule.NOT_REQUEST: NOT_REQUEST, Rule.DROP: BAD_DATAGRAM, Rule.ANY: TOLERATED}
POSE, CYCLE_ON, CYCLE_OFF, PROG_IDX, VISION_RESULT = (Action.POSE, Action.CYCLE_ON, Action.CYCLE_OFF,
                                                       Action.PROG_IDX, Action.VISION_RESULT)
#: the case a wrong code to a well-formed request is filed under, by action (else A3)
_CODE_CASE = {POSE: "S3", Action.REGISTER_POSE: "S3", CYCLE_ON: "S2", Action.NONE: "A4"}
F4_SAMPLE = 16  # frames with values checked for the byte order, per connection and side
_ACTIONS = frozenset(int(a) for a in Action)


def expect(event: Any, ctx: Any, transport: str) -> Expectation:
    """What the box may do with a robot event (the protocol's facts)."""
    tr = Transport.TCP if transport == "tcp" else Transport.UDP
    if type(event) is SnapCut:
        return snap_expectation(event)
    if type(event) is Frame:
        return rule_for_frame(event, ctx.profile, tr)
    return rule_for_error(event, ctx.profile, tr)


class Cycles:
    """The box's cycle state as the capture shows it, per box (and per connection: whether
    the box keeps it per box or per connection is its choice, so both must agree)."""

    def __init__(self) -> None:
        self.boxes: dict[Any, Cycle] = {}

    def state(self, box: Any, conn: Cycle) -> Cycle:
        at_box = self.boxes.get(box, Cycle.UNKNOWN)
        return at_box if at_box == conn else Cycle.UNKNOWN

    def answered(self, box: Any, judge: ConnJudge, action: int | None, code: int) -> None:
        """The cycle after this answer: the session table's (:func:`~conformance.protocol.session_table.cycle_after`)."""
        if action not in CYCLE_ACTIONS:
            return
        new = cycle_after(self.state(box, judge.cycle), action, code)
        self.boxes[box] = new
        judge.cycle = new


def _case(finding: Any, exp: Expectation, action: int | None) -> str | None:
    if finding.key.startswith("answer/"):
        return None  # the answer itself is broken: its frame error is filed already
    if finding.clause == "A1":
        return _CODE_CASE.get(Action(action), "A3") if action in _ACTIONS else "A3"
    if exp.rule is Rule.DROP:
        return "R7"
    if exp.rule in (Rule.REJECT, Rule.NOT_REQUEST) and finding.level is Level.MUST:
        return "R1"
    return str(finding.clause)


def judge_pair(j: ConnJudge, exp: Expectation | None, r_action: int | None, r_event: Any, event: Any, code: int,
               frames: tuple[int, int], r_raw: bytes, raw: bytes, t: float) -> None:
    """The answer ``event`` (code ``code``) to the robot's ``r_event``: file what is wrong, or what was judged."""
    f, label, ctx = j.findings, j.label, j.ctx
    value = None
    if type(event) is Frame and event.blocks:
        value = getattr(event.blocks[0], "value", None)
    cycle = ctx.cycles.state(j.box, j.cycle)
    if exp is None:
        exp = expect(r_event, ctx, j.transport)
    if exp.rule is Rule.ANSWER and r_action in (CYCLE_ON, CYCLE_OFF):
        exp = Expectation(exp.rule, exp.clause, exp.action, exp.message, allowed_codes(r_action, cycle),
                          exp.named_error, exp.values)
    answered_ok = type(event) is Frame
    text = event.describe() if answered_ok else f"[{event.clause}] {event.message}"
    found = judge_answer(exp, Seen(event.action if answered_ok else r_action, code, value, "", text))
    filed = False
    for finding in found:
        case = _case(finding, exp, r_action)
        if case is None or (case in ("S3", "S2", "A3", "A4") and not answered_ok):
            continue
        verdict = broken_verdict(finding.level)
        f.add(case, BOX, verdict, f"{label}: {finding.requirement}; got {text}", frames, robot=r_raw, box=raw)
        filed = True
    if not filed:
        _judged(j, exp, r_action, code, value, cycle, frames, r_raw, raw)
    if code or (r_action == PROG_IDX and value == 409):
        j.refused(t, f"the box answered {action_name(r_action)} with 0x{code:04X}" if code else
                  "the box answered ProgIdx with 409 (E2)")
    ctx.cycles.answered(j.box, j, r_action, code)


def _judged(j: ConnJudge, exp: Expectation, action: int | None, code: int, value: int | None, cycle: Cycle,
            frames: tuple[int, int], r_raw: bytes, raw: bytes) -> None:
    """Nothing wrong: count the judgement, and record the answers PROTOCOL.md allows but a reader wants to see."""
    f, label = j.findings, j.label
    if exp.rule is Rule.DROP:
        f.check("R7", BOX)
        return
    if exp.rule in (Rule.REJECT, Rule.NOT_REQUEST, Rule.REJECT_SHOULD):
        f.check("B4" if exp.rule is Rule.REJECT_SHOULD else "R1", BOX)
        return
    if exp.rule is not Rule.ANSWER:
        return
    case = "E2" if action == PROG_IDX else "E3" if action == VISION_RESULT else _CODE_CASE.get(Action(action), "A3") \
        if action in _ACTIONS else "A3"
    note = None
    if action == CYCLE_ON and code == 1:
        note = "CycleOn answered 0001 (box not ready): the rest of the session is not judged"
    elif action == CYCLE_OFF and code == 2:
        note = "CycleOff answered 0002 (could not close the detection)"
    elif action == PROG_IDX and (value == 409 or code == 409):
        note = "ProgIdx answered 409 (resource conflict): the rest of the session is not judged"
    elif action in (CYCLE_ON, CYCLE_OFF) and code not in (0, 1, 2):
        note = (f"{action_name(action)} answered 0x{code:04X}: the capture does not show the box's cycle state "
                f"({cycle.value}), in which PROTOCOL.md lets it answer so (S3, a MAY)")
    if note:
        f.add(case, BOX, Verdict.INFORMATIONAL, f"{label}: {note}", frames, robot=r_raw, box=raw)
    else:
        f.check(case, BOX)


def unanswered_case(finding: Any) -> str:
    return "R6" if finding.clause == "R6" else ("A3" if finding.clause == "A3" else str(finding.clause))


def byte_order(j: ConnJudge, side: str, event: Any, raw: bytes, offset: int, t: float, last: int) -> None:
    """F4: values absurd as read but plausible byte-swapped (certify-robot's heuristic), sampled."""
    if len(raw) < 14:
        return
    evidence = byte_order_evidence(FrameRecord(0, j.transport, t, offset, raw, event), j.ctx.profile)
    if evidence is None:
        return
    j.f4[side] += 1
    if evidence == "swapped":
        j.f4[side] = F4_SAMPLE  # one is enough
        j.findings.add("F4", side, Verdict.FAIL, f"{j.label}, offset {offset}: the values read as absurd in "
                       f"{j.ctx.profile.byte_order}-endian order but plausible byte-swapped: the {side} writes the "
                       "other byte order", (last,), **{side: raw})
    else:
        j.findings.check("F4", side)


def judge_backlog(j: ConnJudge) -> None:
    """T2 (box): on a stream connection (poses only), the answer latency does not grow."""
    if j.actions != [POSE] or j.transport != "tcp":
        return
    series, ctx = j.pose_latency, j.ctx
    if series.n and (ctx.stream_plot is None or series.max > ctx.stream_plot[0]):
        ctx.stream_plot = (series.max, j.label, series)
    b = backlog(series, ctx.profile.pose_rate_hz)
    if b is None:
        if j.paired_poses:
            j.findings.add("T2", BOX, Verdict.INCONCLUSIVE, f"{j.label}: {j.paired_poses} answered pose(s): too few "
                           "to see a backlog")
        return
    text = (f"{j.label}: last-quarter p50 latency {b.last_p50_ms:.2f} ms, first-quarter p50 {b.first_p50_ms:.2f} ms "
            f"(limit {b.threshold_ms:.2f} ms) over {j.paired_poses:,} poses")
    if b.grows:
        j.findings.add("T2", BOX, Verdict.FAIL, text + ": the latency grows (a backlog)")
    else:
        j.findings.check("T2", BOX)
        j.findings.tally("T2", BOX).note(text)


def count_frames(j: ConnJudge) -> None:
    """How many frames each frame clause judged, both sides."""
    f = j.findings
    rc, bc = dict(j.robot_counts), dict(j.box_counts)
    rc[POSE] = j.poses
    bc[POSE] = bc.get(POSE, 0) + j.box_poses
    n_robot, n_box = sum(rc.values()) + j.robot_errors, sum(bc.values()) + j.box_errors
    tcp = j.transport == "tcp"
    for clause in ("F1", "F2", "F3", "F5", "A5", "B5"):
        f.check(clause, ROBOT, n_robot)
    for clause in ("F1", "F2", "F3", "F5"):
        f.check(clause, BOX, n_box)
    cut_r, cut_b = cut_counts(j, ROBOT), cut_counts(j, BOX)  # frames the capture cut: their content is not judged
    f.check("F6" if tcp else "F7", ROBOT, n_robot - sum(cut_r.values()))
    f.check("F6" if tcp else "F7", BOX, n_box - sum(cut_b.values()))
    rc = {a: n - cut_r.get(a, 0) for a, n in rc.items()}
    bc = {a: n - cut_b.get(a, 0) for a, n in bc.items()}
    poses = rc.get(POSE, 0) + rc.get(Action.REGISTER_POSE, 0)
    f.check("B1", ROBOT, poses)
    f.check("B2", ROBOT, rc.get(Action.TOLERANCE, 0))
    f.check("B3", ROBOT, poses + rc.get(Action.TOLERANCE, 0) + rc.get(PROG_IDX, 0))
    f.check("B4", ROBOT, poses + rc.get(Action.TOLERANCE, 0))
    f.check("E1", ROBOT, rc.get(PROG_IDX, 0))
    f.check("E2", ROBOT, rc.get(PROG_IDX, 0))
    f.check("E3", ROBOT, rc.get(VISION_RESULT, 0))
    f.check("E1", BOX, bc.get(PROG_IDX, 0) + bc.get(VISION_RESULT, 0))

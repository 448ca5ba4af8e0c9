"""Sessions: the connections one robot opens to one box, judged as a whole (robot side).

A session is the connections between one robot address and one box address and port
that overlap in time (the command connection and the stream connections opened while
it is open); it ends when the last of them ends. When it ends it is judged with
certify-robot's session judgement (:mod:`conformance.observed.session`): the canonical
order of S1 (or E4 when the session uses ProgIdx or the result request, or with
``--extension``) across both connections, the robot awaiting each answer on the command
connection (A1/T1), and here also that the robot closes what it opened (S5).

What a capture cannot show is not judged: a session whose first connection was already
open when the capture began is INCONCLUSIVE for S1/E4, and a gap, the box's refusal
(a non-0000 answer, silence, its close) or the end of the capture is a *cut*: what the
robot did not do after it is not judged (certify-robot's rule for a refusal).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Any

from ..model.verdicts import Verdict
from ..observed.connections import BY_BOX, BY_ROBOT, BY_ROBOT_RESET, ConnRecord, SessionRecord
from ..observed.robot_frames import FrameRecord
from ..observed.session import Cut, SessionView, awaited, build_view, judge_order
from ..protocol import Action, action_name
from .analysis_context import Context
from .capture_timing import StreamJudgement
from .findings import ROBOT

__all__ = ["SPLIT_AFTER_S", "SPLIT_CONNECTIONS", "ConnOutcome", "ObservedView", "Session", "SessionTracker"]

#: a session takes at most this many connections, and no new one once it is this old: the next starts a new
#: session (several robots behind one address, a connection open for a week: memory stays flat)
SPLIT_CONNECTIONS = 64
SPLIT_AFTER_S = 3600.0
#: a stream's rate (T2) is judged from this many intervals on (the robot stopped after a refusal: a few poses)
MIN_RATE_INTERVALS = 8


@dataclass
class ConnOutcome:
    """What a finished connection leaves for its session's judgement."""

    record: ConnRecord
    requests: list[FrameRecord]  # the non-pose requests, in order (conn 0: renumbered by the session)
    first_pose: tuple[float, int, int, Any] | None  # (t, frame, offset, event)
    pose_after: tuple[float, int, int, Any] | None  # the first pose after the session's first CycleOn
    handshake: bool
    gap_t: float | None
    refusals: list[tuple[float, str]]
    frame_at: dict[float, int]
    label: str
    open_at_end: bool
    t_end: float
    stream: StreamJudgement
    number: int


@dataclass
class ObservedView(SessionView):
    """certify-robot's session view; its times also name the capture's frame."""

    frame_at: dict[float, int] = field(default_factory=dict)

    def ms(self, t: float | None) -> str:
        text = super().ms(t)
        frame = self.frame_at.get(t) if t is not None else None
        return f"{text} (frame {frame})" if frame else text


class Session:
    def __init__(self, number: int, key: tuple[str, str, int], t0: float) -> None:
        self.number = number
        self.key = key
        self.t0 = t0
        self.open = 0
        self.conns: list[Any] = []  # the live connections (their judges get the first CycleOn)
        self.outcomes: list[ConnOutcome] = []
        self.cycle_on: float | None = None
        self.seen = 0  # connections attached so far
        self.split_at: float | None = None  # when a new connection went to a new session instead
        self.continues: int | None = None  # the number of the session this one was split from

    def on_cycle_on(self, t: float) -> None:
        if self.cycle_on is None:
            self.cycle_on = t
            for conn in self.conns:
                conn.judge.want_pose_after = t

    @property
    def label(self) -> str:
        robot, box, port = self.key
        return f"session {self.number} (robot {robot} → box {box}:{port})"


class SessionTracker:
    def __init__(self, ctx: Context) -> None:
        self.ctx = ctx
        self.open: dict[tuple[str, str, int], Session] = {}
        self.count = 0

    def attach(self, conn: Any) -> Session:
        key = (conn.robot[0], conn.box[0], conn.box[1])
        session = self.open.get(key)
        previous = None
        if session is not None and (session.seen >= SPLIT_CONNECTIONS or conn.t_open - session.t0 > SPLIT_AFTER_S):
            # split: the old session keeps its open connections and is judged when they end; it is cut here
            session.split_at = conn.t_open
            previous, session = session, None
            del self.open[key]
        if session is None:
            self.count += 1
            self.ctx.stats.sessions += 1
            session = self.open[key] = Session(self.count, key, conn.t_open)
            if previous is not None:
                session.continues = previous.number
        session.open += 1
        session.seen += 1
        session.conns.append(conn)
        conn.judge.on_cycle_on = session.on_cycle_on
        if session.cycle_on is not None:
            conn.judge.want_pose_after = session.cycle_on
        return session

    def done(self, conn: Any, outcome: ConnOutcome) -> None:
        session: Session = conn.session
        session.outcomes.append(outcome)
        session.open -= 1
        if conn in session.conns:
            session.conns.remove(conn)
        if session.open <= 0:
            if self.open.get(session.key) is session:
                del self.open[session.key]
            judge_session(self.ctx, session)


def judge_session(ctx: Context, session: Session) -> None:
    outcomes = sorted(session.outcomes, key=lambda o: (o.record.t_open, o.number))
    records: list[ConnRecord] = []
    frames: dict[int, list[FrameRecord]] = {}
    frame_at: dict[float, int] = {}
    for n, o in enumerate(outcomes, 1):
        record = dataclasses.replace(o.record, number=n)
        records.append(record)
        kept = [dataclasses.replace(r, conn=n) for r in o.requests]
        have = {r.offset for r in kept}
        for pose in (o.first_pose, o.pose_after):
            if pose is not None:
                t, frame, offset, event = pose
                frame_at.setdefault(t, frame)
                if offset not in have:  # the first pose may be the first in the cycle, or kept already: once
                    have.add(offset)
                    kept.append(FrameRecord(n, "tcp", t, offset, b"", event))
        frames[n] = sorted(kept, key=lambda r: r.t)
        frame_at.update({t: f for t, f in o.frame_at.items() if t not in frame_at})
    t_end = max(o.t_end for o in outcomes)
    base = build_view(SessionRecord(session.number, session.t0, records, t_end, "capture"), ctx.profile)
    view = ObservedView(**{f.name: getattr(base, f.name) for f in dataclasses.fields(SessionView)},
                        frame_at=frame_at)
    view.frames = frames
    view.cut = _cut(view, outcomes)
    if session.split_at is not None and (view.cut is None or view.cut.t > session.split_at):
        view.cut = Cut(session.split_at, f"the session was split there (more than {SPLIT_CONNECTIONS} connections, "
                                         f"or older than {SPLIT_AFTER_S:g} s): what follows is a new session")
    label = session.label
    extension = ctx.config.extension
    if extension is None:
        extension = any(a in (Action.PROG_IDX, Action.VISION_RESULT) for o in outcomes for a in o.record.actions)
    _order(ctx, view, outcomes, label, extension, session.continues)
    _awaited(ctx, view, label)
    _closes(ctx, view, outcomes, label)
    _streams(ctx, outcomes)


def _cut(view: SessionView, outcomes: list[ConnOutcome]) -> Cut | None:
    cuts = [view.cut] if view.cut is not None else []
    for o in outcomes:
        cuts += [Cut(t, why) for t, why in o.refusals]
        if o.gap_t is not None:
            cuts.append(Cut(o.gap_t, f"the capture has a gap on {o.label}"))
        if o.open_at_end:
            cuts.append(Cut(o.t_end, f"the capture ends while {o.label} is open"))
    return min(cuts, key=lambda c: c.t) if cuts else None


def _order(ctx: Context, view: ObservedView, outcomes: list[ConnOutcome], label: str, extension: bool,
           continues: int | None = None) -> None:
    clause = "E4" if extension else "S1"
    f = ctx.findings
    first = outcomes[0]
    seen = [r for rs in view.frames.values() for r in rs if r.action is not None]
    if not first.handshake or continues is not None:
        actions = sorted({r.action for r in seen if r.action is not None})
        why = (f"it continues session {continues}, split there (too many or too old connections)"
               if first.handshake else f"the capture starts mid-session ({first.label} was already open)")
        f.add(clause, ROBOT, Verdict.INCONCLUSIVE,
              f"{label}: {why}: the order is not judged; "
              f"seen: {', '.join(action_name(a) for a in actions) or 'no request'}",
              (view.frame_at.get(first.record.t_open, 0),))
        return
    result = judge_order(view, extension)
    steps = "; ".join(f"{name} {view.ms(t)}" for name, t in result.steps.items())
    lines = [*result.violations, *result.missing]
    frames = sorted({n for n in view.frame_at.values()})[:1]
    if result.failed and len(view.commands) > 1:
        f.add(clause, ROBOT, Verdict.INCONCLUSIVE, f"{label}: {crowded(view)}; not judged: {'; '.join(lines)} "
              f"[steps: {steps}]", frames)
    elif result.failed:
        f.add(clause, ROBOT, Verdict.FAIL, f"{label}: {'; '.join(lines)} [steps: {steps}]", frames)
    elif result.not_judged:
        cut = view.cut
        f.add(clause, ROBOT, Verdict.INCONCLUSIVE,
              f"{label}: at {view.ms(cut.t if cut else None)} {cut.why if cut else 'the session was cut'}; not judged "
              f"after it: {', '.join(result.not_judged)} [steps: {steps}]", frames)
    else:
        f.check(clause, ROBOT)
        f.tally(clause, ROBOT).note(f"{label}: all {len(result.steps)} steps in order [steps: {steps}]"
                                    + (f" ({'; '.join(result.notes)})" if result.notes else ""))


def crowded(view: SessionView) -> str:
    """Why a session with several command connections is not judged as one robot's."""
    return (f"{len(view.commands)} command connections from one address at once: several robots behind one address "
            "(NAT), or one robot opening several; which connection belongs to which session cannot be told from "
            "the wire (certify-robot, or a capture per robot, tells)")


def _awaited(ctx: Context, view: ObservedView, label: str) -> None:
    if not view.commands:
        return
    checked, bad = awaited(view, ctx.profile)
    f = ctx.findings
    f.check("A1", ROBOT, checked)
    for line in bad:
        f.add("A1", ROBOT, Verdict.FAIL, f"{label}: {line}")


def _closes(ctx: Context, view: ObservedView, outcomes: list[ConnOutcome], label: str) -> None:
    f = ctx.findings
    cmd = view.cmd
    cmd_closed = cmd.t_close if cmd is not None and cmd.closed_by in (BY_ROBOT, BY_ROBOT_RESET) else None
    linger = ctx.config.linger_s
    for o, record in zip(outcomes, view.session.conns):
        if record.closed_by == BY_BOX:
            continue  # the box closed first: nothing to judge of the robot
        late = None
        if cmd_closed is not None and record is not cmd:
            end = record.t_close if record.t_close is not None else o.t_end
            if end - cmd_closed > linger:
                late = end - cmd_closed
        if late is not None and len(view.commands) > 1:
            f.add("S5", ROBOT, Verdict.INCONCLUSIVE, f"{label}: {o.label} outlived a command connection by "
                  f"{late:.1f} s; {crowded(view)}")
        elif late is not None:
            what = "closed" if record.t_close is not None else "still open when the capture ends"
            f.add("S5", ROBOT, Verdict.FAIL, f"{label}: {o.label} {what} {late:.1f} s after the command connection "
                  f"closed (more than --linger {linger:g} s): the robot left it open",
                  (view.frame_at.get(record.t_close, 0),) if record.t_close is not None else ())
        elif record.closed_by in (BY_ROBOT, BY_ROBOT_RESET):
            f.check("S5", ROBOT)
        elif o.open_at_end:
            f.add("S5", ROBOT, Verdict.INCONCLUSIVE, f"{label}: {o.label} is open when the capture ends")


def _streams(ctx: Context, outcomes: list[ConnOutcome]) -> None:
    f = ctx.findings
    for o in outcomes:
        if o.record.role != "stream":
            continue
        j = o.stream
        if not j.blocks or j.poses <= MIN_RATE_INTERVALS:  # a few poses' "rate" is the machine's scheduling
            f.add("T2", ROBOT, Verdict.INCONCLUSIVE, f"{o.label}: {j.poses} pose(s): too few to measure a rate "
                  f"(at least {MIN_RATE_INTERVALS + 1})")
            continue
        tally = f.tally("T2", ROBOT)
        if len(tally.details.setdefault("streams", [])) < 20:
            tally.details["streams"].append({"connection": o.label, "figures": j.described[:2],
                                             "windows_hz": j.windows_hz[:120]})
        if j.ok and j.starved:
            f.add("T2", ROBOT, Verdict.INCONCLUSIVE, f"{o.label}: {j.starved}")
            continue
        if j.ok:
            f.check("T2", ROBOT)
            tally.note(f"{o.label}: {j.rate_text}; {j.jitter_text}")
            continue
        texts = [t for ok, t in ((j.rate_ok, j.rate_text), (j.jitter_ok, j.jitter_text)) if not ok]
        f.add("T2", ROBOT, Verdict.FAIL, f"{o.label}: {'; '.join(texts)} ({j.described[0] if j.described else ''})",
              (o.first_pose[1],) if o.first_pose else ())


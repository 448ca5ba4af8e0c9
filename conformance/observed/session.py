"""Canonical-order tracking (S1, E4) and awaited answers (A1/T1) for one session, sans-I/O.

:func:`build_view` sorts a session's connections into the command connection, the
stream connection(s) and the rest, and finds the *cut*: the first moment the box
answered something other than 0000 (CycleOn 0001, a malformed frame's 1001, ProgIdx
409, …), stayed silent on bytes that were not a request, or closed a connection itself
(``--inject close-mid-cycle``). A robot may stop its session there, so what it did not
do after the cut is INCONCLUSIVE, not FAIL (S2); what it did before is judged.

The canonical sessions are the session table's (:mod:`conformance.protocol.session_table`), as the
robot simulator plays them: each step's *milestone* gets the time it was first observed, and
:func:`judge_order` checks that every milestone happened, in that order, with each
command sent once, except CycleOn and CycleOff: a robot may prime several parts in one
session, so CycleOn → CycleOff pairs may repeat between stream on and stream off, each
CycleOn closed by its CycleOff before the next (the milestone "CycleOn" is the first,
"CycleOff" the last). S1's milestones are connect → stream on → CycleOn → CycleOff →
stream off → disconnect; what the source's own calls send in between is legal (a NONE
"ping" before anything, a pose or a register pose on the command connection as
``ISIGHT(3,35)`` / ``ISIGHT(3,36)`` send them, tolerances with any number of blocks,
stream answers read late).
"""

from __future__ import annotations

from dataclasses import dataclass, field

from ..protocol import Action, Profile, ResultCode, action_name
from ..protocol.session_table import (
    E4,
    E4_ONLY,
    E4_RESULT_WAIT_S,
    FREE_ACTIONS,
    S1,
    commands,
    ends_session,
    milestones,
)
from .connections import BY_BOX, BY_ROBOT, BY_ROBOT_RESET, BY_SUITE, ConnRecord, Exchange, SessionRecord
from .robot_frames import FrameRecord, decode_conn

#: the canonical sessions' milestones, as an observer times them (the session table's S1 and E4)
S1_STEPS: tuple[str, ...] = milestones(S1)
E4_STEPS: tuple[str, ...] = milestones(E4)
#: Commands of each canonical session, in order (each once, except the cycle pairs; a 27 may repeat after a 202).
S1_COMMANDS = commands(S1)
E4_COMMANDS = commands(E4)
#: A request sent this close to the bound after the previous one counts as "waited time_out".
WAIT_SLACK = 0.98


@dataclass(frozen=True)
class Cut:
    t: float
    why: str


@dataclass
class SessionView:
    session: SessionRecord
    frames: dict[int, list[FrameRecord]]
    exchanges: dict[tuple[int, int], Exchange]
    cmd: ConnRecord | None
    commands: list[ConnRecord]  # every command-role connection (cmd first)
    streams: list[ConnRecord]
    silent: list[ConnRecord]  # TCP connections that sent no request
    cut: Cut | None
    t0: float

    def ms(self, t: float | None) -> str:
        return "never" if t is None else f"+{(t - self.t0) * 1000:.1f} ms"

    def requests(self, conn: ConnRecord) -> list[FrameRecord]:
        return [r for r in self.frames.get(conn.number, []) if r.action is not None]

    def pose_times(self, conn: ConnRecord) -> list[float]:
        return [r.t for r in self.requests(conn) if r.action == Action.POSE]

    def answer(self, rec: FrameRecord) -> Exchange | None:
        return self.exchanges.get((rec.conn, rec.offset))

    def before_cut(self, t: float | None) -> bool:
        return t is not None and (self.cut is None or t <= self.cut.t)


def build_view(session: SessionRecord, profile: Profile, interrupted: str = "") -> SessionView:
    """The session sorted out. ``interrupted``: the run was stopped (a signal) during this
    session, which is then a cut at its end (what did not happen is not judged)."""
    frames = {c.number: decode_conn(c, profile) for c in session.conns}
    exchanges = {(c.number, e.offset): e for c in session.conns for e in c.exchanges}
    tcp = session.tcp
    commands = [c for c in tcp if c.role == "command"]
    silent = [c for c in tcp if c.role == "unknown"]
    streams = [c for c in tcp if c.role == "stream"]
    if not commands and silent and (not streams or silent[0].t_open <= streams[0].t_open):
        # S1's command connection says nothing until CycleOn: a robot that stopped before
        # it leaves a silent first connection, which is its command connection
        commands, silent = [silent[0]], silent[1:]
    t0 = min([session.t_start, *(c.t_open for c in session.conns)])
    view = SessionView(session, frames, exchanges, commands[0] if commands else None, commands, streams, silent,
                       None, t0)
    view.cut = find_cut(view)
    if interrupted and session.t_end is not None and (view.cut is None or view.cut.t > session.t_end):
        view.cut = Cut(session.t_end, f"the run was interrupted ({interrupted})")
    return view


def runs_extension(conns: list[ConnRecord]) -> bool:
    """The robot ran the revision's session (E4): it sent ProgIdx or the result request (``--extension auto``)."""
    return any(a in E4_ONLY for c in conns for a in c.actions)


def find_cut(view: SessionView) -> Cut | None:
    """The first refusal by the box: a non-0000 answer, silence on a non-request, a close."""
    cuts: list[Cut] = []
    for conn in view.session.conns:
        for ex in conn.exchanges:
            where = f"on connection {conn.number} ({conn.role})"
            what = action_name(ex.action)
            if ex.answer is None and ex.reaction in ("silent", "close"):
                cuts.append(Cut(ex.t_request, f"the box did not answer {what} {where} (A5)"))
            elif ends_session(ex.action, ex.error_code, ex.value):  # the session table: a robot may stop here (S2)
                text = (f"the box answered {what} with 0x{ex.error_code:04X} {where}" if ex.error_code
                        else f"the box answered ProgIdx with 409 {where} (E2)")
                cuts.append(Cut(ex.t_answer or ex.t_request, text))
        if conn.closed_by == BY_BOX and conn.t_close is not None:
            cuts.append(Cut(conn.t_close, f"the box closed connection {conn.number} ({conn.close_note})"))
    return min(cuts, key=lambda c: c.t) if cuts else None


@dataclass
class OrderResult:
    steps: dict[str, float | None]
    violations: list[str] = field(default_factory=list)
    missing: list[str] = field(default_factory=list)  # FAIL: skipped, or never done without a cut
    not_judged: list[str] = field(default_factory=list)  # INCONCLUSIVE: after the cut
    notes: list[str] = field(default_factory=list)

    @property
    def failed(self) -> bool:
        return bool(self.violations or self.missing)


def observe_steps(view: SessionView) -> dict[str, float | None]:
    cmd, stream = view.cmd, (view.streams[0] if view.streams else None)
    first: dict[int, float] = {}
    last_off: float | None = None
    for conn in view.commands:
        for rec in view.requests(conn):
            action = rec.action
            assert action is not None
            first[action] = min(first.get(action, rec.t), rec.t)
            if action == Action.CYCLE_OFF and view.before_cut(rec.t):
                last_off = rec.t if last_off is None else max(last_off, rec.t)
    poses = view.pose_times(stream) if stream else []
    on, off = first.get(Action.CYCLE_ON), last_off if last_off is not None else first.get(Action.CYCLE_OFF)
    in_cycle = [t for t in poses if on is not None and t > on and (off is None or t < off)]
    closed = (BY_ROBOT, BY_ROBOT_RESET)
    return {
        "command connect": cmd.t_open if cmd else None,
        "ProgIdx": first.get(Action.PROG_IDX),
        "stream connect": stream.t_open if stream else None,
        "first pose": poses[0] if poses else None,
        "CycleOn": on,
        "pose during the cycle": in_cycle[0] if in_cycle else None,
        "CycleOff": off,
        "stream close": stream.t_close if stream and stream.closed_by in closed else None,
        "result request": first.get(Action.VISION_RESULT),
        "command disconnect": cmd.t_close if cmd and cmd.closed_by in closed else None,
    }


def judge_order(view: SessionView, extension: bool) -> OrderResult:
    names = E4_STEPS if extension else S1_STEPS
    seen = observe_steps(view)
    result = OrderResult({n: seen[n] for n in names})
    if not any(view.requests(c) for c in view.session.conns):
        result.violations.append("the robot sent no request the box could read: no session took place")
        return result
    # 1. every step, in the canonical order. After the cut the robot may stop or tear its
    # session down in any order: nothing after it is judged.
    judged = view.before_cut
    latest: tuple[float, str] | None = None
    for i, name in enumerate(names):
        t = seen[name]
        if t is None or not judged(t):
            later = [n for n in names[i + 1 :] if judged(seen[n])]
            if t is None and (view.cut is None or later):
                result.missing.append(_missing(view, name, later))
            elif view.cut is not None:
                result.not_judged.append(name)
            continue
        if latest is not None and t < latest[0]:
            result.violations.append(f"{name} at {view.ms(t)} came {(latest[0] - t) * 1000:.2f} ms before "
                                     f"{latest[1]} at {view.ms(latest[0])}; the canonical order puts it after")
        if latest is None or t >= latest[0]:
            latest = (t, name)
    # 2. each command once (the cycle pairs in turn), nothing foreign on the command connection
    expected = E4_COMMANDS if extension else S1_COMMANDS
    counts: dict[int, int] = {}
    previous: FrameRecord | None = None
    cycles = _CyclePairs(view)
    for conn in view.commands:
        for rec in view.requests(conn):
            if not judged(rec.t):
                continue
            action = rec.action
            assert action is not None
            polled = (action == Action.VISION_RESULT and previous is not None and previous.action == action
                      and (view.answer(previous) or Exchange(0, 0, None, "")).value == ResultCode.BUSY)
            previous = rec
            if action in FREE_ACTIONS or polled:
                continue
            if action in (Action.CYCLE_ON, Action.CYCLE_OFF):
                result.violations.extend(cycles.add(rec))
                continue
            counts[action] = counts.get(action, 0) + 1
            if action not in expected and counts[action] == 1:
                hint = " (the revision's session: rerun with --extension if the robot implements E4)" \
                    if action in (Action.PROG_IDX, Action.VISION_RESULT) else ""
                result.violations.append(f"{action_name(action)} at {view.ms(rec.t)} is not part of the canonical "
                                         f"{'E4' if extension else 'S1'} session{hint}")
            elif action in expected and counts[action] == 2:
                result.violations.append(f"{action_name(action)} sent again at {view.ms(rec.t)}; the canonical "
                                         "session sends it once")
    if view.cut is None:
        result.violations.extend(cycles.unclosed())
    # 3. one command and one stream connection
    for extra, what in ((view.commands[1:], "command"), (view.streams[1:], "stream")):
        extra = [c for c in extra if judged(c.t_open)]
        if extra:
            result.violations.append(f"{len(extra) + 1} {what} connections (also {', '.join(c.label for c in extra)}); "
                                     f"the canonical session opens one")
    for conn in view.silent:
        result.notes.append(f"{conn.label} sent nothing (opened {view.ms(conn.t_open)}, closed {view.ms(conn.t_close)})")
    if seen["stream connect"] is not None and seen["pose during the cycle"] is None and judged(seen["CycleOff"]):
        result.notes.append("no pose was streamed during the cycle (noted; T2 judges the stream)")
    if extension and seen["result request"] is not None and seen["stream close"] is not None:
        waited = seen["result request"] - seen["stream close"]
        if 0 <= waited < E4_RESULT_WAIT_S:
            result.notes.append(f"the result request came {waited * 1000:.0f} ms after Send_Pos_Off; the revision "
                                f"waits {E4_RESULT_WAIT_S:g} s (noted, not judged)")
    return result


class _CyclePairs:
    """CycleOn and CycleOff in turn: each CycleOn closed by its CycleOff before the next one."""

    def __init__(self, view: SessionView) -> None:
        self.view = view
        self.open_at: float | None = None  # the CycleOn of the cycle that is on
        self.closed_at: float | None = None  # the CycleOff that closed the last cycle

    def add(self, rec: FrameRecord) -> list[str]:
        ms = self.view.ms
        if rec.action == Action.CYCLE_ON:
            if self.open_at is not None:
                return [f"CYCLE_ON sent again at {ms(rec.t)} while the cycle its CycleOn at {ms(self.open_at)} opened "
                        "is still on; each CycleOn is closed by its CycleOff before the next"]
            self.open_at = rec.t
            return []
        if self.open_at is None:
            after = f"the CycleOff at {ms(self.closed_at)} already closed the last cycle" \
                if self.closed_at is not None else "no CycleOn came before it"
            return [f"CYCLE_OFF sent again at {ms(rec.t)}: {after}"]
        self.open_at, self.closed_at = None, rec.t
        return []

    def unclosed(self) -> list[str]:
        if self.open_at is None or self.closed_at is None:
            return []  # no cycle closed at all: S1's "CycleOff missing" says it
        return [f"the CycleOn at {self.view.ms(self.open_at)} is never closed by a CycleOff"]


#: how a close the robot never made reads in S1's missing steps (the suite closed it after --linger)
LEFT_OPEN = "the robot left it open"


def _missing(view: SessionView, name: str, later: list[str]) -> str:
    why = ""
    if name in ("stream close", "command disconnect"):
        conn = view.cmd if name == "command disconnect" else (view.streams[0] if view.streams else None)
        if conn is not None and conn.closed_by == BY_SUITE:
            why = f": {LEFT_OPEN} ({conn.close_note})"
        elif conn is None:
            why = ": there is no such connection"
    elif name in ("stream connect", "first pose") and not view.streams:
        why = ": no connection carried only poses"
    elif name == "command connect" and view.cmd is None:
        why = ": no connection carried a command"
    if later:
        why += f" (skipped: {', '.join(later[:2])} happened)"
    return f"{name} missing{why}"


# -- A1/T1: the command connection waits for each answer ---------------------------------------------
@dataclass(frozen=True)
class NotAwaited:
    """A request (or close) on a command connection before the previous request's answer or time-out."""

    conn: int
    prev: FrameRecord  # the request whose answer was not awaited
    cur: FrameRecord | None  # the request sent too early (None: the robot closed the connection)
    answered: float | None  # when the answer to ``prev`` went out (None: never)
    text: str


def awaited(view: SessionView, profile: Profile) -> tuple[int, list[str]]:
    """(requests checked, violations): on command connections a request follows the previous
    one's answer, or time_out (vision_time_out after a 27) without one; a close too."""
    checked, bad = not_awaited(view, profile)
    return checked, [b.text for b in bad]


def not_awaited(view: SessionView, profile: Profile) -> tuple[int, list[NotAwaited]]:
    """:func:`awaited` with the frames that show each violation."""
    checked, bad = 0, list[NotAwaited]()
    for conn in view.commands:
        requests = view.requests(conn)
        for prev, cur in zip(requests, [*requests[1:], None]):
            bound = profile.answer_bound_s(prev.action)
            ex = view.answer(prev)
            answered = ex.t_answer if ex is not None else None
            if cur is None:  # the last request: the robot may close only after the answer or the bound
                t_next, what = conn.t_close, "closed the connection"
                if conn.closed_by not in (BY_ROBOT, BY_ROBOT_RESET):
                    continue
            else:
                t_next, what = cur.t, f"sent {action_name(cur.action or 0)}"
            assert t_next is not None
            if cur is not None:
                checked += 1
            if (answered is not None and answered <= t_next) or t_next - prev.t >= bound * WAIT_SLACK:
                continue
            if answered is None and view.cut is not None and t_next > view.cut.t:
                continue  # after the box's refusal (silence, a malformed or non-0000 answer) the robot may move on
            state = (f"its answer went out at {view.ms(answered)}" if answered is not None
                     else "no answer was coming (the box stays silent on it)")
            bad.append(NotAwaited(conn.number, prev, cur, answered,
                                  f"connection {conn.number}: {what} at {view.ms(t_next)}, "
                                  f"{(t_next - prev.t) * 1000:.1f} ms after {action_name(prev.action or 0)} "
                                  f"({view.ms(prev.t)}) and before its answer; {state}; the robot waits up to "
                                  f"{bound * 1000:.0f} ms"))
    return checked, bad

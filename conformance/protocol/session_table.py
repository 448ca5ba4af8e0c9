"""The session table: the cycle's and the session's transitions as data, in the style of h11's ``_state.py``.

Everything that follows a session reads it from here: the fuzz session machine, ``analyze``,
the observed sessions (``certify-robot``), the reference box and the robot simulator.

* :data:`CYCLE_AFTER` — what an answer to CycleOn or CycleOff tells a tester about the
  cycle (S2, S3, A3): ``(action, error code)`` → the cycle state after it, or :data:`KEEP`.
  Any code the table does not list leaves the state :attr:`Cycle.UNKNOWN`; any other action
  leaves it as it was (S3: poses, tolerances, ProgIdx and the result request are answered in
  or out of a cycle). :func:`cycle_after` reads it.
* :data:`STEPS` — every step of a canonical session, with the request it sends (if any)
  and the milestone an observer times it by; :data:`S1` and :data:`E4` — the canonical
  orders (PROTOCOL.md S1, E4), as steps.
* :data:`FREE_ACTIONS` — requests a robot may send on the command connection anywhere in
  its session; :func:`ends_session` — the answers after which a robot may stop its session
  (S2: what it did not do then is INCONCLUSIVE, not FAIL).

Where PROTOCOL.md leaves a state open the table says UNKNOWN, and what is allowed in it is the
set of every allowed behaviour (:data:`~.answers.ALLOWED_CODES`). A box knows its own state:
where a tester's is UNKNOWN the box keeps its own (:func:`box_cycle_after`, its choice).
"""

from __future__ import annotations

import enum
from dataclasses import dataclass

from .constants import Action, ErrorCode, ResultCode


class Cycle(str, enum.Enum):
    """The box's cycle state as a tester knows it (S2, S3)."""

    IDLE = "idle"
    ON = "on"
    UNKNOWN = "unknown"  # e.g. the cycle state is per box and another connection may have changed it


class _Keep(enum.Enum):
    KEEP = "keep"


#: the answer leaves the cycle state as it was
KEEP = _Keep.KEEP

#: (action, error code) -> the cycle after that answer (a tester's view); a code not listed: UNKNOWN
CYCLE_AFTER: dict[tuple[Action, int], Cycle | _Keep] = {
    # S2: CycleOn 0000 starts the cycle (or, S3, it was on already and stays on)
    (Action.CYCLE_ON, ErrorCode.OK): Cycle.ON,
    # S2: 0001, not ready: no cycle started, whatever was before still is
    (Action.CYCLE_ON, ErrorCode.NOT_READY): KEEP,
    # S1/S3: CycleOff 0000 ends the cycle (or there was none)
    (Action.CYCLE_OFF, ErrorCode.OK): Cycle.IDLE,
    # A3: 0002, "CycleOff did not close the detection properly": whether the cycle is still on,
    # PROTOCOL.md does not say; CycleOn twice and CycleOff without CycleOn both MAY be answered
    # either way (S3), so what follows is judged against every state
    (Action.CYCLE_OFF, ErrorCode.CYCLE_OFF_FAILED): Cycle.UNKNOWN,
}
#: the actions whose answers change the cycle (every other request's leave it as it was, S3)
CYCLE_ACTIONS = frozenset({Action.CYCLE_ON, Action.CYCLE_OFF})


def cycle_after(cycle: Cycle, action: int, code: int) -> Cycle:
    """The cycle state a tester knows after ``action`` was answered ``code`` in ``cycle``."""
    if action not in CYCLE_ACTIONS:
        return cycle
    after = CYCLE_AFTER.get((Action(action), code), Cycle.UNKNOWN)
    return cycle if after is KEEP else after


def box_cycle_after(cycle: Cycle, action: int, code: int) -> Cycle:
    """The reference box's own state after it answered ``code``: the table's, and where a tester
    cannot know it, the box keeps its state (a refused CycleOn leaves the cycle off, a failed
    CycleOff leaves it on)."""
    after = cycle_after(cycle, action, code)
    return cycle if after is Cycle.UNKNOWN else after


class Io(str, enum.Enum):
    """What a step of a session does."""

    CONNECT = "connect"  # the command connection opens (ISIGHT(1))
    COMMAND = "command"  # one request on the command connection, its answer awaited
    STREAM_ON = "stream-on"  # Send_Pos_On: the stream connection opens, poses flow
    TRAJECTORY = "trajectory"  # the primer trajectory: poses on the stream during the cycle
    STREAM_OFF = "stream-off"  # Send_Pos_Off: the poses stop, the stream connection closes
    WAIT = "wait"  # E4: a pause before the result request
    DISCONNECT = "disconnect"  # the command connection closes (ISIGHT(2))


@dataclass(frozen=True)
class SessionStep:
    name: str  # the step's name (the robot simulator's ``--steps``)
    io: Io
    action: Action | None = None  # the request a COMMAND step sends
    milestone: str | None = None  # what an observer times the step by (None: not a milestone of the order)


STEPS: dict[str, SessionStep] = {s.name: s for s in (
    SessionStep("connect", Io.CONNECT, milestone="command connect"),
    SessionStep("ping", Io.COMMAND, Action.NONE),
    SessionStep("prog_idx", Io.COMMAND, Action.PROG_IDX, milestone="ProgIdx"),
    SessionStep("send_pos_on", Io.STREAM_ON, milestone="stream connect"),
    SessionStep("cycle_on", Io.COMMAND, Action.CYCLE_ON, milestone="CycleOn"),
    SessionStep("trajectory", Io.TRAJECTORY),
    SessionStep("cycle_off", Io.COMMAND, Action.CYCLE_OFF, milestone="CycleOff"),
    SessionStep("send_pos_off", Io.STREAM_OFF, milestone="stream close"),
    SessionStep("result_wait", Io.WAIT),
    SessionStep("vision_result", Io.COMMAND, Action.VISION_RESULT, milestone="result request"),
    SessionStep("disconnect", Io.DISCONNECT, milestone="command disconnect"),
)}

#: S1: configure → connect → Send_Pos_On → CycleOn → trajectory → CycleOff → Send_Pos_Off → disconnect
S1: tuple[SessionStep, ...] = tuple(STEPS[n] for n in (
    "connect", "send_pos_on", "cycle_on", "trajectory", "cycle_off", "send_pos_off", "disconnect"))
#: E4: connect → ProgIdx → Send_Pos_On → CycleOn → trajectory → CycleOff → Send_Pos_Off → wait 1 s →
#: result request (bounded by vision_time_out) → disconnect
E4: tuple[SessionStep, ...] = tuple(STEPS[n] for n in (
    "connect", "prog_idx", "send_pos_on", "cycle_on", "trajectory", "cycle_off", "send_pos_off", "result_wait",
    "vision_result", "disconnect"))
#: E4: the revision waits this long between Send_Pos_Off and the result request.
#: The actions only the revision's session (E4) sends: a robot that sends one runs E4 (``--extension auto``).
E4_ONLY = frozenset({Action.PROG_IDX, Action.VISION_RESULT})
E4_RESULT_WAIT_S = 1.0


def canonical(extension: bool) -> tuple[SessionStep, ...]:
    """The canonical session: E4 with the extension, else S1."""
    return E4 if extension else S1


def milestones(order: tuple[SessionStep, ...]) -> tuple[str, ...]:
    """The order's milestones, as an observer times them."""
    return tuple(s.milestone for s in order if s.milestone is not None)


def commands(order: tuple[SessionStep, ...]) -> tuple[Action, ...]:
    """The order's commands, in order (each once, except CycleOn → CycleOff pairs; a 27 may repeat after a 202)."""
    return tuple(s.action for s in order if s.io is Io.COMMAND and s.action is not None)


#: Requests allowed anywhere on the command connection: the optional ping (NONE), tolerances, and the
#: poses the source's ISIGHT sends there (23: ISIGHT(3,35) the current TP pose; 24: ISIGHT(3,36) a register pose).
FREE_ACTIONS = frozenset({Action.NONE, Action.POSE, Action.REGISTER_POSE, Action.TOLERANCE})


def ends_session(action: int | None, code: int | None, value: int | None = None) -> bool:
    """After this answer a robot may stop its session (S2): any code but 0000 (CycleOn 0001, a parse
    error's 1001 ...), or ProgIdx's 409 in the block (E2)."""
    if code not in (None, ErrorCode.OK):
        return True
    return action == Action.PROG_IDX and value == ResultCode.CONFLICT

"""The robot's canonical sessions as data, sans-I/O: which step does what and what answer it expects.

S1: connect the command connection → ``Send_Pos_On`` (stream connection, poses at
the stream rate) → CycleOn → primer trajectory (``duration`` s) → CycleOff →
``Send_Pos_Off`` (poses stop, the stream closes) → disconnect.

E4: connect → ProgIdx (26) → ``Send_Pos_On`` → CycleOn → trajectory → CycleOff →
``Send_Pos_Off`` → wait 1 s → result request (27, bounded by ``vision_time_out``)
→ disconnect.

The canonical orders, each step's I/O (:class:`~conformance.protocol.session_table.Io`) and the
request it sends are the session table's (:mod:`conformance.protocol.session_table`, like h11's
``_state.py``); :data:`STEP_TABLE` adds, for each step's name, the answer it expects and the
judge that reads that answer. Judges are pure functions (an answer frame in, a :class:`Judgement` out);
the asyncio driver (:mod:`.robot`) does the I/O and asks them. :class:`RobotFaults`
makes the deliberately broken robots. No sockets or clocks live here.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

from ...protocol import Action, ErrorCode, Frame, ProtocolError, ResultCode
from ...protocol.answers import SENDABLE_RESULTS
from ...protocol.frames import ValueBlock
from ...protocol.session_table import E4, S1, Io
from ...protocol.session_table import STEPS as STEPS_OF_TABLE
from .robot_result import EXIT_MISBEHAVED, EXIT_NOT_READY, EXIT_OK, RobotResult


@dataclass(frozen=True)
class Judgement:
    """What a step concludes from one answer."""

    code: int = EXIT_OK  # EXIT_OK: the answer is one the step expects
    reason: str = ""  # why not (one line); with EXIT_OK, an informational note for the timeline
    fatal: bool = False  # end the session even when ``stop_on_error`` is off


PASS = Judgement()

#: ``judge(answer, program index the session sends) -> Judgement``: reads a well-formed answer
#: that echoes its request's action (:func:`judge_answer` checks that first).
Judge = Callable[[Frame, int], Judgement]


@dataclass(frozen=True)
class Step:
    """One step of a session: what it does and, for a command, the request and the answer it expects."""

    io: Io
    does: str
    action: Action | None = None  # Io.COMMAND: the request's action
    carries_index: bool = False  # the request carries the program index in one value block (E1)
    expects: str = ""
    judge: Judge | None = None  # Io.COMMAND: reads the answer
    keep: Callable[[RobotResult, int | None], None] | None = None  # records the answer's value
    bound: str = "time_out"  # the profile's time-out that bounds the answer
    cycle: str | None = None  # "start"/"end": the step starts or ends the cycle the poses follow


def _step(name: str, does: str, **how: Any) -> Step:
    """The step called ``name``: its I/O and request from the session table, the rest as given."""
    step = STEPS_OF_TABLE[name]
    return Step(step.io, does, step.action, **how)


def answer_value(frame: Frame) -> int | None:
    """The value of an answer's first block when it is a value block (type 03), else None."""
    return frame.blocks[0].value if frame.blocks and isinstance(frame.blocks[0], ValueBlock) else None


def judge_malformed(what: str, error: ProtocolError) -> Judgement:
    return Judgement(EXIT_MISBEHAVED, f"malformed answer to {what}: {error}")


def judge_answer(action: Action, frame: Frame) -> Judgement:
    """Any command's answer echoes its request's action (A2)."""
    if frame.action is not action:
        return Judgement(EXIT_MISBEHAVED, f"{action.name} answered with action {frame.action.name} "
                         "(A2: an answer echoes its request's action)")
    return PASS


def judge_pose(seq: int, frame: Frame) -> Judgement:
    """A pose's answer on the stream: action 23 (A2), error code 0000 in or out of a cycle (S3)."""
    if frame.action is not Action.POSE:
        return Judgement(EXIT_MISBEHAVED, f"pose #{seq} answered with action {frame.action.name} (A2)")
    if frame.error_code != ErrorCode.OK:
        return Judgement(EXIT_MISBEHAVED, f"pose #{seq} answered 0x{frame.error_code:04X} where 0000 expected (S3)")
    return PASS


def _zero(clause: str) -> Judge:
    def judge(frame: Frame, program_index: int) -> Judgement:
        if frame.error_code != ErrorCode.OK:
            return Judgement(EXIT_MISBEHAVED, f"{frame.action.name} answered 0x{frame.error_code:04X} where 0000 "
                             f"expected ({clause})")
        return PASS

    return judge


def _judge_cycle_on(frame: Frame, program_index: int) -> Judgement:
    if frame.error_code == ErrorCode.NOT_READY:
        return Judgement(EXIT_NOT_READY, "box not ready (CycleOn answered 0001, S2: the cycle is inconclusive)",
                         fatal=True)
    return _zero("S1")(frame, program_index)


def _judge_prog_idx(frame: Frame, program_index: int) -> Judgement:
    value = answer_value(frame)
    if value == program_index and value != ResultCode.CONFLICT:
        if frame.error_code != ErrorCode.OK:
            return Judgement(reason=f"error field 0x{frame.error_code:04X} ignored (E2: it stays 0000)")
        return PASS
    if value == ResultCode.CONFLICT:
        return Judgement(EXIT_NOT_READY, f"box not ready for program {program_index} (ProgIdx answered 409, E2)",
                         fatal=True)
    return Judgement(EXIT_MISBEHAVED, f"ProgIdx {program_index} answered with value {value}, expected "
                     f"{program_index} or 409 (E2)")


def _judge_vision_result(frame: Frame, program_index: int) -> Judgement:
    value = answer_value(frame)
    if value in (ResultCode.EMPTY, ResultCode.NO_ANSWER):
        return Judgement(EXIT_MISBEHAVED, f"result request answered ResultCode {value}, which only the robot "
                         "writes (E3)")
    if value not in SENDABLE_RESULTS:
        return Judgement(reason=f"unlisted ResultCode {value} (E3: informational)")
    if frame.error_code != ErrorCode.OK:
        return Judgement(reason=f"error field 0x{frame.error_code:04X} ignored (E2/E3: it stays 0000)")
    return PASS


def _keep_prog_idx(result: RobotResult, value: int | None) -> None:
    result.prog_idx_answer = value


def _keep_vision_result(result: RobotResult, value: int | None) -> None:
    result.vision_result = value


#: Every step a session may play, by name (``--steps`` and :class:`~.robot.RobotSession`'s ``steps``).
STEP_TABLE: dict[str, Step] = {
    "connect": _step("connect", "ISIGHT opens the command connection", expects="open within time_out (T1)"),
    "ping": _step("ping", "action 00, the keep-alive", expects="0000 (A4)", judge=_zero("A4")),
    "prog_idx": _step("prog_idx", "ProgIdx: the program index for this cycle", carries_index=True,
                      expects="the same index back; 409: not ready, the cycle is inconclusive (E2)",
                      judge=_judge_prog_idx, keep=_keep_prog_idx),
    "send_pos_on": _step("send_pos_on", "Send_Pos_On: the stream connection, poses at the stream rate",
                         expects="the first pose answered within time_out (T1)"),
    "cycle_on": _step("cycle_on", "CycleOn: detection starts",
                      expects="0000 (S1); 0001: not ready, the cycle is inconclusive (S2)", judge=_judge_cycle_on,
                      cycle="start"),
    "trajectory": _step("trajectory", "the primer trajectory: poses along it for duration seconds",
                        expects="every pose answered 0000 within time_out (S3, T1)"),
    "cycle_off": _step("cycle_off", "CycleOff: detection ends", expects="0000 (S1)",
                       judge=_zero("S1"), cycle="end"),
    "send_pos_off": _step("send_pos_off", "Send_Pos_Off: the poses stop, the stream connection closes",
                          expects="the last poses answered within time_out (T1)"),
    "result_wait": _step("result_wait", "wait result_wait seconds before asking for the result"),
    "vision_result": _step("vision_result", "the result request",
                           expects="a ResultCode the box may send, within vision_time_out (E3, E5)",
                           judge=_judge_vision_result, keep=_keep_vision_result, bound="vision_time_out"),
    "disconnect": _step("disconnect", "ISIGHT closes the command connection",
                        expects="no unsolicited frame before it (A1)"),
}

#: The canonical sessions, as the session table orders them (protocol/session_table.py: S1, E4).
S1_STEPS: tuple[str, ...] = tuple(step.name for step in S1)
E4_STEPS: tuple[str, ...] = tuple(step.name for step in E4)
STEPS = frozenset(STEP_TABLE)


def session_steps(extension: bool = False, ping: bool = False, steps: Sequence[str] | None = None) -> tuple[str, ...]:
    """The steps a session plays: ``steps`` as given, else S1 (E4 with the extension), ``ping`` after connect."""
    if steps is None:
        steps = E4_STEPS if extension else S1_STEPS
        if ping:
            steps = (steps[0], "ping", *steps[1:])
    unknown = [s for s in steps if s not in STEPS]
    if unknown:
        raise ValueError(f"unknown session steps: {', '.join(unknown)}; known: {', '.join(sorted(STEPS))}")
    return tuple(steps)


@dataclass(frozen=True)
class RobotFaults:
    """Deliberate deviations from a conforming robot (all off by default)."""

    #: B4: byte order of pose/tolerance/value block values ("little" breaks B4).
    float_byte_order: str | None = None
    #: B3: index of the first block (1 breaks B3 under the default profile).
    first_index: int | None = None
    #: B1/F5: announce this block length L in pose frames (the body stays 25 bytes).
    block_length: int | None = None
    #: T2: send poses in bursts of this many frames, every ``burst`` periods.
    burst: int = 1
    #: T2: the stream clock slows by this fraction per second (0.1: 10 % longer periods each second).
    drift: float = 0.0
    #: S1/S5: ``Send_Pos_Off`` stops the poses but leaves the stream connection open; it
    #: stays open ``stream_hold_s`` seconds after the command disconnect (or until the box closes it).
    leave_stream_open: bool = False
    stream_hold_s: float = 1.0
    #: R3: send every frame in pieces of this many bytes.
    segment_size: int | None = None
    #: Last word on every frame's bytes: ``hook(frame, data) -> data``.
    encode_hook: Callable[[Frame, bytes], bytes] | None = None

    def __post_init__(self) -> None:
        if self.float_byte_order not in (None, "big", "little"):
            raise ValueError("float_byte_order must be 'big', 'little' or None")
        if self.first_index is not None and not 0 <= self.first_index <= 255:
            raise ValueError("first_index must be 0..255")
        if self.block_length is not None and not 0 <= self.block_length <= 0xFFFF:
            raise ValueError("block_length must be 0..65535")
        if self.burst < 1:
            raise ValueError("burst must be at least 1")
        if self.segment_size is not None and self.segment_size < 1:
            raise ValueError("segment_size must be at least 1")
        if not 0 <= self.stream_hold_s <= 600:
            raise ValueError("stream_hold_s must be 0..600 seconds")


__all__ = [
    "E4_STEPS", "PASS", "S1_STEPS", "STEPS", "STEP_TABLE", "Io", "Judge", "Judgement", "RobotFaults", "Step",
    "answer_value", "judge_answer", "judge_malformed", "judge_pose", "session_steps",
]

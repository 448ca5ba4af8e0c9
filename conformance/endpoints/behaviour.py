"""The reference AI Box's behaviour, sans-I/O: decoder events in, answers out.

No sockets, clocks or tasks live here (``server.py`` and ``protocols.py`` do the I/O). Like h11's
``_state.py``, what the box does is written as tables, not as nested ifs:

* :data:`TRANSITIONS` — a well-formed request: ``(cycle state, action, condition)``
  → ``(reaction, next state, note)``. The *condition* is the one knob that concerns
  the action (:data:`CONDITIONS`): the box is ready (CycleOn), CycleOff succeeds,
  ProgIdx has no conflict; for every other action it is always true.
* :data:`MALFORMED` — a request that is a parse error (B1–B5, E1–E3, F5, F6):
  action → reaction.
* :data:`REACTION_ANSWER` — reaction → the answer's error code and block value.

:class:`BoxBehaviour` compiles the tables against a :class:`BoxConfig` once, with
every constant answer pre-encoded for TCP and UDP, so deciding is one dict lookup.
One TCP connection (framing, and the fast path for the stream's hot case) is
:class:`~.connection.BoxConnection`.

Choices where PROTOCOL.md allows several behaviours (the most helpful one each time):

* **A3 malformed requests** (wrong block type/count/length, index gap, NaN/inf in
  strict profiles, a TCP check that is neither 00 00 nor the CRC, a header announcing
  more than the largest legal frame): 23/24 → 1001, 25 → 1002 (A3's SHOULD).
  01 → 0001 and 02 → 0002: the only codes defined for those actions, and what the
  robot must conclude (no cycle started / detection not closed). 26/27 → one
  type-03 block holding ResultCode 400 "request not understood", with 400 in the
  error field too (a malformed request is never answered 0000). 00 → silence:
  A4 defines only 0000 for action 00, and 0000 is forbidden here.
* **A5 not a request** (bad start word or garbage, version ≠ 00 01, transfer type
  ≠ 01, unknown action, and 26/27 when the extension is off): silence, and the
  decoder resynchronises on the next FE FE (R6). ``BoxConfig.on_garbage="close"``
  closes the connection instead (the other behaviour A5 allows).
* **R7 UDP**: a datagram with a wrong CRC or not exactly one frame long is dropped
  silently; other malformed datagrams get the A3 answers above, CRC-checked.
* **S3**: poses are answered 0000 in or out of a cycle. CycleOn while a cycle is
  on and CycleOff with no cycle on are answered 0000 (informational, noted). The
  cycle state belongs to the box (shared by all connections), since CycleOn comes
  on the command connection and the poses on the stream connection.
* **Request error field**: a request's (undefined) error code field is ignored.
* **E2**: ProgIdx is answered with the same index in one type-03 block, or 409
  when ``progidx_conflict`` is set; 409 travels in the block, and also in the
  error field when the profile's ``progidx_conflict`` is ``"error-code"``.
  A 0001 "not ready" box still answers ProgIdx with the index (E2 readiness is
  the ``progidx_conflict`` knob). E3: the result request is answered with
  ``vision_result`` whatever the cycle did.
* A refused CycleOn (0001) leaves the cycle off; a failed CycleOff (0002) leaves
  it on: the session table (:mod:`conformance.protocol.session_table`) gives each answer's
  next state, and where a tester cannot know it (0002) the box keeps its own.
"""

from __future__ import annotations

import enum
from collections.abc import Callable
from dataclasses import dataclass
from typing import NamedTuple

from ..protocol import (
    DEFAULT_PROFILE,
    Action,
    ErrorCode,
    Frame,
    Profile,
    ProtocolError,
    ResultCode,
    TransferType,
    Transport,
    ValueBlock,
    answer,
    codec_for,
    value_blocks,
)
from ..protocol.answers import SENDABLE_RESULTS, allowed_codes, request_action
from ..protocol.constants import EXTENSION_ACTIONS
from ..protocol.session_table import Cycle, box_cycle_after


class Reaction(str, enum.Enum):
    """What the box does with one event."""

    OK = "ok"  # answer, error 0000
    NOT_READY = "not-ready"  # 0001 (S2)
    CYCLE_OFF_FAILED = "cycle-off-failed"  # 0002 (A3)
    POSE_ERROR = "pose-error"  # 1001 (A3)
    TOLERANCE_ERROR = "tolerance-error"  # 1002 (A3)
    PROG_IDX = "prog-idx"  # 26: the same index back (E2)
    PROG_IDX_CONFLICT = "prog-idx-conflict"  # 26: 409 (E2)
    VISION_RESULT = "vision-result"  # 27: the configured ResultCode (E3)
    NOT_UNDERSTOOD = "not-understood"  # malformed 26/27: ResultCode 400
    SILENT = "silent"  # no answer; keep reading
    CLOSE = "close"  # no answer; close the connection


class Transition(NamedTuple):
    reaction: Reaction
    next_state: Cycle
    note: str


#: Which knob decides each action's outcome (absent: the condition is always true).
CONDITIONS: dict[Action, str] = {
    Action.CYCLE_ON: "ready",
    Action.CYCLE_OFF: "cycle_off_succeeds",
    Action.PROG_IDX: "prog_idx_free",
}

_IDLE, _ON = Cycle.IDLE, Cycle.ON
#: The states the box itself knows (a tester may not know it: protocol.answers.Cycle.UNKNOWN).
BOX_STATES = (_IDLE, _ON)
_ALWAYS = {  # state-independent requests: action -> (reaction when true, reaction when false)
    Action.NONE: (Reaction.OK, Reaction.OK),
    Action.POSE: (Reaction.OK, Reaction.OK),
    Action.REGISTER_POSE: (Reaction.OK, Reaction.OK),
    Action.TOLERANCE: (Reaction.OK, Reaction.OK),
    Action.PROG_IDX: (Reaction.PROG_IDX, Reaction.PROG_IDX_CONFLICT),
    Action.VISION_RESULT: (Reaction.VISION_RESULT, Reaction.VISION_RESULT),
}

_CYCLE_CODE = {Reaction.OK: ErrorCode.OK, Reaction.NOT_READY: ErrorCode.NOT_READY,
               Reaction.CYCLE_OFF_FAILED: ErrorCode.CYCLE_OFF_FAILED}


def _cycle(state: Cycle, action: Action, reaction: Reaction, note: str) -> Transition:
    """A CycleOn/CycleOff transition: its next state is the session table's (where a tester cannot know
    the state, the box keeps its own: :func:`~conformance.protocol.session_table.box_cycle_after`)."""
    return Transition(reaction, box_cycle_after(state, action, _CYCLE_CODE[reaction]), note)


#: Well-formed requests: (state, action, condition) -> (reaction, next state, note).
TRANSITIONS: dict[tuple[Cycle, Action, bool], Transition] = {
    (_IDLE, Action.CYCLE_ON, True): _cycle(_IDLE, Action.CYCLE_ON, Reaction.OK, "S2: cycle started"),
    (_IDLE, Action.CYCLE_ON, False): _cycle(_IDLE, Action.CYCLE_ON, Reaction.NOT_READY, "S2: box not ready, 0001"),
    (_ON, Action.CYCLE_ON, True): _cycle(_ON, Action.CYCLE_ON, Reaction.OK,
                                         "S3: CycleOn while a cycle is on, 0000 (informational)"),
    (_ON, Action.CYCLE_ON, False): _cycle(_ON, Action.CYCLE_ON, Reaction.NOT_READY,
                                          "S2: box not ready, 0001 (cycle stays on)"),
    (_ON, Action.CYCLE_OFF, True): _cycle(_ON, Action.CYCLE_OFF, Reaction.OK, "S1: cycle stopped"),
    (_ON, Action.CYCLE_OFF, False): _cycle(_ON, Action.CYCLE_OFF, Reaction.CYCLE_OFF_FAILED, "A3: CycleOff failed, 0002"),
    (_IDLE, Action.CYCLE_OFF, True): _cycle(_IDLE, Action.CYCLE_OFF, Reaction.OK,
                                            "S3: CycleOff with no cycle on, 0000 (informational)"),
    (_IDLE, Action.CYCLE_OFF, False): _cycle(_IDLE, Action.CYCLE_OFF, Reaction.CYCLE_OFF_FAILED,
                                             "A3: CycleOff failed, 0002"),
    **{
        (state, action, cond): Transition(pair[0] if cond else pair[1], state, "")
        for state in BOX_STATES
        for action, pair in _ALWAYS.items()
        for cond in (True, False)
    },
}

#: A malformed request (parse error with a readable request header) -> reaction (A3).
MALFORMED: dict[Action, Reaction] = {
    Action.NONE: Reaction.SILENT,
    Action.CYCLE_ON: Reaction.NOT_READY,
    Action.CYCLE_OFF: Reaction.CYCLE_OFF_FAILED,
    Action.POSE: Reaction.POSE_ERROR,
    Action.REGISTER_POSE: Reaction.POSE_ERROR,
    Action.TOLERANCE: Reaction.TOLERANCE_ERROR,
    Action.PROG_IDX: Reaction.NOT_UNDERSTOOD,
    Action.VISION_RESULT: Reaction.NOT_UNDERSTOOD,
}

#: reaction -> (error code, block value or None). PROG_IDX's value is the request's,
#: VISION_RESULT's is the configured result; both are filled in by the compiler.
REACTION_ANSWER: dict[Reaction, tuple[int, int | None]] = {
    Reaction.OK: (ErrorCode.OK, None),
    Reaction.NOT_READY: (ErrorCode.NOT_READY, None),
    Reaction.CYCLE_OFF_FAILED: (ErrorCode.CYCLE_OFF_FAILED, None),
    Reaction.POSE_ERROR: (ErrorCode.POSE_ERROR, None),
    Reaction.TOLERANCE_ERROR: (ErrorCode.TOLERANCE_ERROR, None),
    Reaction.PROG_IDX: (ErrorCode.OK, 0),
    Reaction.PROG_IDX_CONFLICT: (ErrorCode.OK, ResultCode.CONFLICT),
    Reaction.VISION_RESULT: (ErrorCode.OK, ResultCode.OK),
    Reaction.NOT_UNDERSTOOD: (ResultCode.NOT_UNDERSTOOD, ResultCode.NOT_UNDERSTOOD),
}

_KNOWN_ACTIONS = frozenset(int(a) for a in Action)
#: UDP errors that R7 says to drop silently: wrong CRC, not exactly one frame.
_UDP_DROP = frozenset({"F7", "F5"})


@dataclass(frozen=True)
class BoxConfig:
    """The reference box's knobs."""

    profile: Profile = DEFAULT_PROFILE
    #: S2: answer CycleOn with 0001.
    not_ready: bool = False
    #: A3: answer CycleOff with 0002.
    cycle_off_fails: bool = False
    #: Delay every answer by this many milliseconds (T1 testing); order is kept.
    latency_ms: float = 0.0
    #: E3: the ResultCode of the answer to a result request (27).
    vision_result: int = ResultCode.OK
    #: E2: answer ProgIdx with 409 (resource conflict / not ready).
    progidx_conflict: bool = False
    #: E: implement actions 26/27; off, they are unknown actions (A5, silence).
    extension: bool = True
    #: A5: what to do with bytes that are not a request: "silent" or "close".
    on_garbage: str = "silent"

    def __post_init__(self) -> None:
        if self.vision_result not in SENDABLE_RESULTS:
            raise ValueError(
                f"vision result must be one of {', '.join(map(str, SENDABLE_RESULTS))} (E3), not {self.vision_result}"
            )
        if not 0 <= self.latency_ms <= 600_000:
            raise ValueError(f"latency must be 0..600000 ms, not {self.latency_ms}")
        if self.on_garbage not in ("silent", "close"):
            raise ValueError("on_garbage must be 'silent' or 'close'")

    @property
    def conditions(self) -> dict[str, bool]:
        return {
            "ready": not self.not_ready,
            "cycle_off_succeeds": not self.cycle_off_fails,
            "prog_idx_free": not self.progidx_conflict,
        }


@dataclass(frozen=True, slots=True)
class Decision:
    """What the box does with one event: the answer (frame and its bytes) or none."""

    reaction: Reaction
    frame: Frame | None = None
    tcp: bytes | None = None
    udp: bytes | None = None
    note: str = ""

    @property
    def close(self) -> bool:
        return self.reaction is Reaction.CLOSE

    def data(self, transport: Transport) -> bytes | None:
        return self.tcp if transport is Transport.TCP else self.udp


@dataclass
class BoxStats:
    requests: int = 0  # well-formed requests decided (fast-path poses included)
    answers: int = 0
    malformed: int = 0  # parse errors with a request header (answered per A3)
    not_requests: int = 0  # A5 events (garbage, wrong version/direction/action)
    dropped_datagrams: int = 0  # R7


class BoxBehaviour:
    """The box's decisions and cycle state, shared by all its connections."""

    def __init__(self, config: BoxConfig = BoxConfig()) -> None:
        self.state = Cycle.IDLE
        self.prog_idx: int | None = None
        self.stats = BoxStats()
        #: Let connections answer valid one-pose frames without calling :meth:`decide`.
        #: Connections opened while it is False route every frame through ``decide`` (set it
        #: False when replacing ``decide`` to plant a defect).
        self.fast_path = True
        self.configure(config)

    # -- compilation ---------------------------------------------------------------------
    def configure(self, config: BoxConfig) -> None:
        """(Re)compile the tables for ``config``; the cycle state is kept.

        Knobs apply at once; a new profile applies to connections opened afterwards
        (each connection's decoder is made for the profile it opened with).
        """
        self.config = config
        self.profile = profile = config.profile
        self.codec = codec_for(profile)
        conditions = config.conditions
        self._first = profile.first_index
        self._prog_idx_cache: dict[int, Decision] = {}
        #: (state, action) -> (decision, next state); absent: not a request (A5)
        self._table: dict[tuple[Cycle, Action], tuple[Decision, Cycle]] = {}
        for (state, action, cond), (reaction, nxt, note) in TRANSITIONS.items():
            if action in EXTENSION_ACTIONS and not config.extension:
                continue
            knob = CONDITIONS.get(action)
            if cond != (conditions[knob] if knob else True):
                continue
            decision = self._build(action, reaction, note)
            allowed = allowed_codes(action, state)
            if decision.frame is not None and allowed is not None and decision.frame.error_code not in allowed:
                raise AssertionError(f"the box's table answers {action.name} in state {state.value} with "
                                     f"{decision.frame.error_code:04X}; the protocol allows {sorted(allowed)}")
            self._table[(state, action)] = (decision, nxt)
        self._malformed: dict[Action, Decision] = {}
        for action, reaction in MALFORMED.items():
            if action in EXTENSION_ACTIONS and not config.extension:
                continue
            code, _ = REACTION_ANSWER.get(reaction, (None, None))
            what = f"0x{code:04X}" if code is not None else reaction.value
            self._malformed[action] = self._build(action, reaction, f"A3: malformed {action.name} request -> {what}")
        garbage = Reaction.CLOSE if config.on_garbage == "close" else Reaction.SILENT
        self._not_request = Decision(garbage, note=f"A5: not a request -> {garbage.value}")
        self._udp_drop = Decision(Reaction.SILENT, note="R7: datagram dropped")
        # the hot path: the answer to a valid pose
        self.pose_ok = self._table[(Cycle.IDLE, Action.POSE)][0].tcp or b""

    def _build(self, action: Action, reaction: Reaction, note: str, value: int | None = None) -> Decision:
        if reaction in (Reaction.SILENT, Reaction.CLOSE):
            return Decision(reaction, note=note)
        code, block_value = REACTION_ANSWER[reaction]
        profile = self.profile
        if reaction is Reaction.VISION_RESULT:
            block_value = self.config.vision_result
        elif reaction is Reaction.PROG_IDX and value is not None:
            block_value = value
        elif reaction is Reaction.PROG_IDX_CONFLICT and profile.progidx_conflict == "error-code":
            code = ResultCode.CONFLICT
        blocks = value_blocks([block_value], self._first) if block_value is not None else ()
        frame = answer(action, code, blocks)
        return Decision(
            reaction, frame, self.codec.encode(frame, Transport.TCP), self.codec.encode(frame, Transport.UDP), note
        )

    # -- deciding ------------------------------------------------------------------------
    def decide(self, event: Frame | ProtocolError, transport: Transport = Transport.TCP) -> Decision:
        """The box's answer to one decoder event (a Frame or a ProtocolError).

        Updates the cycle state and the counters. ``decision.frame`` is the answer
        (None for silence); ``decision.tcp``/``.udp`` are its bytes.
        """
        stats = self.stats
        if type(event) is Frame:
            entry = self._table.get((self.state, event.action))
            if entry is None or event.transfer_type is not TransferType.ROBOT_TO_BOX:
                stats.not_requests += 1
                decision = self._not_request
            else:
                stats.requests += 1
                decision, self.state = entry
                if decision.reaction is Reaction.PROG_IDX:
                    decision = self._prog_idx(event)
        elif isinstance(event, ProtocolError):
            decision = self._error(event, transport)
        else:
            raise TypeError(f"not a decoder event: {event!r}")
        if decision.frame is not None:
            stats.answers += 1
        return decision

    def _prog_idx(self, frame: Frame) -> Decision:
        block = frame.blocks[0]
        assert isinstance(block, ValueBlock), frame  # the codec let through E2's one type-03 block only
        value = block.value
        self.prog_idx = value
        decision = self._prog_idx_cache.get(value)
        if decision is None:
            decision = self._build(Action.PROG_IDX, Reaction.PROG_IDX, f"E2: program index {value} accepted", value)
            if len(self._prog_idx_cache) < 1024:
                self._prog_idx_cache[value] = decision
        return decision

    def _error(self, error: ProtocolError, transport: Transport) -> Decision:
        stats = self.stats
        if transport is not Transport.TCP and error.clause in _UDP_DROP:
            stats.dropped_datagrams += 1
            return self._udp_drop
        action = self.request_action(error)
        if action is None:
            stats.not_requests += 1
            return self._not_request
        stats.malformed += 1
        return self._malformed[action]

    def request_action(self, error: ProtocolError) -> Action | None:
        """The action of the request ``error`` is about (one this box implements), or None when it is
        not a request (A5)."""
        action = request_action(error.header)
        if action is None or action not in _KNOWN_ACTIONS:
            return None
        return Action(action) if Action(action) in self._malformed else None

    # -- UDP -----------------------------------------------------------------------------
    def receive_datagram(self, data: bytes, trace: Tracer | None = None) -> bytes | None:
        """F7/R7: one datagram in, the answer datagram (with its CRC) or None out."""
        try:
            event: Frame | ProtocolError = self.codec.parse(data, Transport.UDP, TransferType.ROBOT_TO_BOX)
        except ProtocolError as exc:
            event = exc
        decision = self.decide(event, Transport.UDP)
        if trace is not None:
            trace(bytes(data), event, decision)
        return decision.udp


#: ``trace(raw bytes in, event, decision)``: called for every event when logging.
Tracer = Callable[[bytes, "Frame | ProtocolError", Decision], None]

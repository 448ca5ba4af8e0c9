"""What a box may answer: the protocol's facts about answers, as data (sans-I/O).

Everything that judges or produces answers reads them from here once: the
reference box picks one answer from these sets, the fuzz oracle, the cases and
``certify-robot`` accept any of them.

* :data:`ALLOWED_CODES` — a well-formed request: (cycle state, action) → the error
  codes a conforming box may answer (A3, A4, S2, S3). ``None``: any code (a MAY).
* :data:`SENDABLE_RESULTS` — the ResultCodes a box may send (E3).
* :func:`rule_for_frame` / :func:`rule_for_error` — what a box may do with one event
  of a receiver's framing: a well-formed request MUST be answered (A1) with an
  allowed code; a parse error of a request MUST NOT be answered 0000 (A3, R1) and
  SHOULD get A3's error where A3 names one; bytes that are not a request MUST NOT be
  answered 0000 (A5) but may get silence, an error or a close; a UDP datagram with a
  bad CRC or length SHOULD be dropped (R7); where PROTOCOL.md leaves the choice open,
  anything goes.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass, replace
from math import isfinite

from .codec import codec_for
from .constants import (
    ACTION_ERROR,
    EXTENSION_ACTIONS,
    HEADER_LEN,
    START_WORD,
    VERSION,
    Action,
    BlockType,
    ResultCode,
    TransferType,
    Transport,
)
from .errors import DirectionError, FloatError, ProtocolError, StartWordError, UnknownActionError, VersionError
from .frames import Frame, Header, ToleranceBlock, ValueBlock
from .levels import Level
from .profile import Profile
from .session_table import Cycle

#: E3: ResultCodes only the robot writes (its initial value, and "no answer" on vision_time_out).
ROBOT_RESULTS = frozenset({ResultCode.EMPTY, ResultCode.NO_ANSWER})
#: Result codes a box may send (E3): every ResultCode but the robot's own.
SENDABLE_RESULTS: tuple[int, ...] = tuple(int(r) for r in ResultCode if r not in ROBOT_RESULTS)


def block_value(raw: bytes, byte_order: str = "big") -> int | None:
    """The int32 of an answer's one type-03 block (a ProgIdx or a ResultCode), read from the bytes even when the
    answer is malformed (a ResultCode E3 does not allow, say); None when it carries no such block."""
    value_at = HEADER_LEN + 1  # the block's index byte, then its int32 (E1)
    if len(raw) < value_at + 4 or raw[6] != BlockType.VALUE or raw[7] != 1:
        return None
    return int.from_bytes(raw[value_at:value_at + 4], "little" if byte_order == "little" else "big", signed=True)


#: E3: the ResultCode of a 26/27 request the box did not understand.
NOT_UNDERSTOOD = int(ResultCode.NOT_UNDERSTOOD)
#: E2: resource conflict / not ready.
CONFLICT = int(ResultCode.CONFLICT)


_ANY = None
#: A well-formed request in a cycle state -> the error codes a box may answer (None: any).
ALLOWED_CODES: dict[tuple[Cycle, Action], frozenset[int] | None] = {}
for _state in Cycle:
    for _action in Action:
        ALLOWED_CODES[(_state, _action)] = frozenset({0})
    # S2: CycleOn 0000, or 0001 when the box is not ready; CycleOn twice MAY be an error (S3)
    ALLOWED_CODES[(_state, Action.CYCLE_ON)] = frozenset({0, 1}) if _state is Cycle.IDLE else _ANY
    # A3: CycleOff 0000 or 0002; CycleOff without CycleOn MAY be an error (S3)
    ALLOWED_CODES[(_state, Action.CYCLE_OFF)] = frozenset({0, 2}) if _state is Cycle.ON else _ANY
    # E2: 409 travels in the block [decision], or in the error field (the other reading)
    ALLOWED_CODES[(_state, Action.PROG_IDX)] = frozenset({0, CONFLICT})
    # E3: the result travels in the block; the error field is not judged
    ALLOWED_CODES[(_state, Action.VISION_RESULT)] = _ANY
del _state, _action
#: S1: on a ready box the canonical session completes with every answer 0000 (its CycleOff too)
CANONICAL_CODES = frozenset({0})


def allowed_codes(action: int, cycle: Cycle = Cycle.UNKNOWN) -> frozenset[int] | None:
    """The error codes a box may answer a well-formed ``action`` request with (None: any)."""
    return ALLOWED_CODES[(cycle, Action(action))]


def allowed_values(frame: Frame) -> frozenset[int] | None:
    """E2/E3: the block values an answer to ``frame`` may carry (None: no block is judged)."""
    if frame.action is Action.PROG_IDX:
        return frozenset({frame.blocks[0].value, CONFLICT})  # type: ignore[union-attr]
    if frame.action is Action.VISION_RESULT:
        return frozenset(SENDABLE_RESULTS)
    return None


def request_action(header: Header | None) -> int | None:
    """The action of a readable robot→box request header (start word, version and
    transfer type right), else None: bytes that are not a request (A5)."""
    h = header
    if h is None or h.start_word != START_WORD or h.version != VERSION or h.transfer_type != TransferType.ROBOT_TO_BOX:
        return None
    return h.action


class Rule(str, enum.Enum):
    """What a box may do with one event of a receiver's framing."""

    ANSWER = "answer"  # a well-formed request: MUST be answered (A1) with an allowed code
    ANSWER_SHOULD = "answer-should"  # F6: a correct CRC in a TCP check field SHOULD be accepted
    REJECT = "reject"  # a parse error of a request: MUST NOT be answered 0000 (A3, R1)
    REJECT_SHOULD = "reject-should"  # B4: NaN/inf SHOULD be a parse error (0000 is NON-STRICT)
    NOT_REQUEST = "not-request"  # A5: never 0000; silence, an error or a close are all fine
    DROP = "drop"  # R7: never 0000, and SHOULD be dropped silently
    ANY = "any"  # PROTOCOL.md leaves the choice open


@dataclass(frozen=True, slots=True)
class Expectation:
    """What a box may do with one event (a frame, or bytes that are not one)."""

    rule: Rule
    clause: str  # "" for a well-formed request, else the first clause the bytes break
    action: int | None  # the request's action when its header is readable
    message: str
    ok_errors: frozenset[int] | None = None  # ANSWER: acceptable error codes (None: any)
    named_error: int | None = None  # A3: the error the box SHOULD answer
    values: frozenset[int] | None = None  # 26/27: acceptable block values of the answer
    after_error: bool = False  # follows a parse error in the same bytes (R6: resync is a SHOULD)
    probe: bool = False  # the valid probe request a tester sends behind the bytes it judges
    damaged: bool = False  # a UDP datagram with a wrong CRC or length too: dropping it silently is right (R7)

    @property
    def valid(self) -> bool:
        return self.rule in (Rule.ANSWER, Rule.ANSWER_SHOULD)

    def describe(self) -> str:
        what = f"[{self.clause}] " if self.clause else ""
        return f"{what}{self.message} -> {self.rule.value}"

    def after(self) -> Expectation:
        return replace(self, after_error=True)


_NOT_REQUEST = (StartWordError, VersionError, DirectionError, UnknownActionError)
_SHAPE_CLAUSES = frozenset({"B1", "B2", "B3", "B5"})


def rule_for_frame(frame: Frame, profile: Profile, transport: Transport = Transport.TCP, extension: bool = True,
                   cycle: Cycle = Cycle.UNKNOWN) -> Expectation:
    """What a box may do with a frame that parses (a well-formed request, mostly)."""
    action = int(frame.action)
    desc = frame.describe()
    if frame.transfer_type is not TransferType.ROBOT_TO_BOX:
        return Expectation(Rule.NOT_REQUEST, "F3", action, f"{desc}: not a robot→box frame")
    if frame.action in EXTENSION_ACTIONS and not extension:
        return Expectation(Rule.NOT_REQUEST, "A5", action, f"{desc}: action {action:02X} without extension E")
    if frame.error_code:
        return Expectation(Rule.ANY, "", action, f"{desc}: non-zero error field in a request (PROTOCOL.md is silent)")
    if transport is Transport.TCP and frame.check:
        return Expectation(Rule.ANSWER_SHOULD, "F6", action, f"{desc} with a CRC in its TCP check field",
                           ok_errors=allowed_codes(action, cycle), values=allowed_values(frame))
    if not profile.strict and non_finite(frame):
        return Expectation(Rule.ANY, "B4", action, f"{desc} with NaN/infinity (lenient profile)")
    if not profile.strict and frame.blocks and frame.blocks[0].index != profile.first_index:
        # lenient: the codec takes either first index (B3's [decision]), a box may take only its own
        return Expectation(Rule.ANY, "B3", action, f"{desc} from first index {frame.blocks[0].index} (lenient profile)")
    return Expectation(Rule.ANSWER, "", action, desc, ok_errors=allowed_codes(action, cycle),
                       values=allowed_values(frame))


def non_finite(frame: Frame) -> bool:
    """B4: a pose or tolerance value is NaN or infinite."""
    for block in frame.blocks:
        if isinstance(block, ValueBlock):
            return False
        values = (block.tolerance,) if isinstance(block, ToleranceBlock) else block.pose
        if not all(isfinite(v) for v in values):
            return True
    return False


def rule_for_error(error: ProtocolError, profile: Profile, transport: Transport = Transport.TCP,
                   extension: bool = True) -> Expectation:
    """What a box may do with bytes that do not parse (a typed error of the codec)."""
    clause, msg = error.clause, error.message
    if transport is Transport.UDP:
        if clause in ("F7", "F5"):
            return Expectation(Rule.DROP, clause, request_action(error.header), msg)
        damage = codec_for(profile).datagram_damage(error.raw)
        if damage is not None:  # R7 lets a receiver that checks the datagram first drop it; one that reads
            exp = _rule_for_error(error, profile, extension)  # the header first treats it as any such error
            return replace(exp, damaged=True, message=f"{msg}; and {damage[0]}: {damage[1]}")
    return _rule_for_error(error, profile, extension)


def _rule_for_error(error: ProtocolError, profile: Profile, extension: bool) -> Expectation:
    clause = error.clause
    action = request_action(error.header)
    msg = error.message
    if isinstance(error, _NOT_REQUEST) or action is None:
        return Expectation(Rule.NOT_REQUEST, clause, action, msg)
    if action in EXTENSION_ACTIONS and not extension:
        return Expectation(Rule.NOT_REQUEST, "A5", action, f"{msg} (action {action:02X} without extension E)")
    named = ACTION_ERROR.get(Action(action)) if action in _ACTIONS else None
    if clause == "F6":
        return Expectation(Rule.ANY, clause, action, f"{msg} (a TCP receiver SHOULD ignore the check field)")
    if isinstance(error, FloatError):
        if not profile.strict:
            return Expectation(Rule.ANY, clause, action, msg)
        return Expectation(Rule.REJECT_SHOULD, clause, action, msg, named_error=named)
    return Expectation(Rule.REJECT, clause, action, msg, named_error=named if clause in _SHAPE_CLAUSES else None)


_ACTIONS = frozenset(int(a) for a in Action)


def zero_allowed_for_malformed(action: int | None, value: int | None) -> bool:
    """E3: a malformed 26/27 request answered with ResultCode 400 ("not understood") in
    its block is not an answer 0000, whatever its error field says."""
    return action in EXTENSION_ACTIONS and value == NOT_UNDERSTOOD


@dataclass(frozen=True, slots=True)
class Seen:
    """One thing the box sent back, reduced to what attribution needs."""

    action: int | None  # the action byte (None: not frame-like at all)
    error: int | None  # the error code field
    value: int | None = None  # the first type-03 block's value, if any
    problem: str = ""  # the clause the answer itself breaks ("" for a conforming answer)
    text: str = ""  # how reports describe it


@dataclass(frozen=True, slots=True)
class Finding:
    level: Level  # MUST or SHOULD
    clause: str
    requirement: str
    observed: str
    key: str  # one key per way of failing (clause/rule/action/what), for telling failures apart


# -- judging one answer (judge_answer, unanswered) ---------------------------------------


def _key(exp: Expectation, what: str) -> str:
    if exp.probe:
        return f"probe/{what}"
    action = f"{exp.action:02X}" if exp.action is not None and exp.action in _ACTIONS else "-"
    return f"{exp.clause or 'valid'}/{exp.rule.value}/{action}/{what}"


def judge_answer(exp: Expectation, seen: Seen) -> list[Finding]:
    """What is wrong with ``seen`` as the answer to the event ``exp`` (empty: nothing)."""
    out: list[Finding] = []
    what = seen.text or f"answered action {seen.action} error {seen.error}"
    if seen.problem:
        out.append(Finding(Level.MUST, seen.problem, f"{seen.problem}: the box's answers are conforming frames", what,
                           f"answer/{seen.problem}"))
    err, rule = seen.error, exp.rule
    if rule is Rule.ANSWER:
        if exp.ok_errors is not None and err not in exp.ok_errors:
            codes = " or ".join(f"{c:04X}" for c in sorted(exp.ok_errors))
            out.append(Finding(Level.MUST, "A1", f"A1/A3: a well-formed request ({exp.message}) is answered {codes}", what,
                               _key(exp, "code")))
        else:
            out.extend(_values(exp, seen, what))
    elif rule is Rule.ANSWER_SHOULD:  # accepted: any answer the request itself may get (a CycleOff's 0002 too)
        rejected = zero_allowed_for_malformed(exp.action, seen.value)  # E3: a 26/27 refused with "400 not understood"
        if rejected or (exp.ok_errors is not None and err not in exp.ok_errors):
            out.append(Finding(Level.SHOULD, exp.clause, f"F6: a TCP receiver SHOULD accept a correct CRC ({exp.message})",
                               what, _key(exp, "code")))
        else:  # accepted, so E2/E3 judge the block as for any 26/27
            out.extend(_values(exp, seen, what))
    elif rule in (Rule.REJECT, Rule.NOT_REQUEST, Rule.DROP):
        if err == 0 and not zero_allowed_for_malformed(exp.action, seen.value):
            req = {Rule.REJECT: "A3/R1: a request that is a parse error MUST NOT be answered 0000",
                   Rule.NOT_REQUEST: "A5/R1: a frame that is not a request MUST NOT be answered 0000",
                   Rule.DROP: "R7: a datagram with a wrong CRC or length MUST NOT be answered 0000"}[rule]
            out.append(Finding(Level.MUST, exp.clause, f"{req} ({exp.message})", what, _key(exp, "0000")))
        elif rule is Rule.DROP:
            out.append(Finding(Level.SHOULD, "R7", f"R7: such a datagram SHOULD be dropped silently ({exp.message})", what,
                               _key(exp, "answered")))
        elif exp.named_error is not None and err != exp.named_error:
            out.append(Finding(Level.SHOULD, "A3", f"A3: a {exp.clause} parse error SHOULD be answered "
                                               f"{exp.named_error:04X} ({exp.message})", what, _key(exp, "code")))
    elif rule is Rule.REJECT_SHOULD:
        if err == 0:
            out.append(Finding(Level.SHOULD, "B4", f"B4: NaN or infinity SHOULD be treated as a parse error ({exp.message})",
                               what, _key(exp, "0000")))
        elif exp.named_error is not None and err != exp.named_error:
            out.append(Finding(Level.SHOULD, "A3", f"A3: a B4 parse error SHOULD be answered {exp.named_error:04X}", what,
                               _key(exp, "code")))
    return out


def _values(exp: Expectation, seen: Seen, what: str) -> list[Finding]:
    """E2/E3: the block of an accepted 26/27 answer holds a value the request may get."""
    if exp.values is None or seen.value in exp.values:
        return []
    clause = "E2" if exp.action == 0x26 else "E3"
    allowed = ", ".join(str(v) for v in sorted(exp.values))
    return [Finding(Level.MUST, clause, f"{clause}: the answer to {exp.message} carries {allowed}", what,
                    _key(exp, "value"))]


def unanswered(exp: Expectation, after_garbage: bool, how: str) -> list[Finding]:
    """What is wrong with the box not answering the event ``exp`` at all."""
    if exp.damaged:
        return []
    if exp.rule is Rule.ANSWER:
        if after_garbage:
            return [Finding(Level.SHOULD, "R6", f"R6: after bytes that are not a frame the box SHOULD resynchronise on the "
                                            f"next valid frame ({exp.message} got no answer)", how, _key(exp, "resync"))]
        return [Finding(Level.MUST, "A1", f"A1: a well-formed request ({exp.message}) is answered", how,
                        _key(exp, "unanswered"))]
    if exp.rule is Rule.ANSWER_SHOULD:
        return [Finding(Level.SHOULD, exp.clause, f"F6: a TCP receiver SHOULD accept a correct CRC ({exp.message})", how,
                        _key(exp, "unanswered"))]
    if exp.rule in (Rule.REJECT, Rule.REJECT_SHOULD) and exp.named_error is not None:
        return [Finding(Level.SHOULD, "A3", f"A3: a {exp.clause} parse error SHOULD be answered {exp.named_error:04X} "
                                        f"({exp.message})", how, _key(exp, "unanswered"))]
    return []

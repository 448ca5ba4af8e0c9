"""The fuzz oracle: what PROTOCOL.md lets a box do with some bytes, and whether it did.

:func:`expectations` decodes the bytes with the codec's reference
:class:`~conformance.protocol.StreamDecoder` (the reading a conforming box must
share) and turns every event into an :class:`Expectation`: a well-formed request
MUST be answered (A1) with an acceptable code; a parse error of a request MUST NOT
be answered 0000 (A3, R1) and SHOULD get A3's error where A3 names one; bytes that
are not a request MUST NOT be answered 0000 (A5) but may get silence, an error or a
close; UDP datagrams with a bad CRC or length SHOULD be dropped (R7); and where
PROTOCOL.md leaves the choice open (a non-zero TCP check, a request error field,
NaN in a lenient profile) anything goes.

When the bytes end inside a frame (a truncated frame, a header whose counts were
mutated), :func:`expectations` also returns the zero *filler* that completes the
frame, so that the probe sent behind it starts on a frame boundary for any box
that frames like the reference decoder.

:func:`judge` compares what the box did (the outcomes before the probe's answer, and
how the exchange ended) with the expectations, in order (A1), and returns findings:
FAIL for a broken MUST, NON-STRICT for a broken SHOULD.
"""

from __future__ import annotations

import enum
import struct
from collections.abc import Sequence
from dataclasses import dataclass, field
from math import isfinite

from ..endpoints.behaviour import SENDABLE_RESULTS
from ..harness.client import Answer, Closed, Malformed, Outcome, Silence
from ..protocol import (
    ACTION_ERROR,
    EXTENSION_ACTIONS,
    HEADER_LEN,
    Action,
    AnswerError,
    DirectionError,
    FloatError,
    Frame,
    Profile,
    ProtocolError,
    StartWordError,
    StreamDecoder,
    ToleranceBlock,
    TransferType,
    Transport,
    UnknownActionError,
    ValueBlock,
    VersionError,
    decode_datagram,
)
from ..suite.verdicts import Verdict

_NOT_REQUEST = (StartWordError, VersionError, DirectionError, UnknownActionError)
_SHAPE_CLAUSES = frozenset({"B1", "B2", "B3", "B5"})
_ACTION_ERROR: dict[int, int] = {int(a): int(e) for a, e in ACTION_ERROR.items()}
#: ResultCode a box sends when it did not understand a 26/27 request (E3).
NOT_UNDERSTOOD = 400
CONFLICT = 409


class Rule(str, enum.Enum):
    """What a box may do with one event of the reference decoding."""

    ANSWER = "answer"  # a well-formed request: MUST be answered (A1) with an acceptable code
    ANSWER_SHOULD = "answer-should"  # F6: a correct CRC in a TCP check field SHOULD be accepted
    REJECT = "reject"  # a parse error of a request: MUST NOT be answered 0000 (A3, R1)
    REJECT_SHOULD = "reject-should"  # B4: NaN/inf SHOULD be a parse error (0000 is NON-STRICT)
    NOT_REQUEST = "not-request"  # A5: never 0000; silence, an error or a close are all fine
    DROP = "drop"  # R7: never 0000, and SHOULD be dropped silently
    ANY = "any"  # PROTOCOL.md leaves the choice open


@dataclass(frozen=True, slots=True)
class Expectation:
    rule: Rule
    clause: str  # "" for a well-formed request, else the first clause the bytes break
    action: int | None  # the request's action when its header is readable
    message: str
    ok_errors: frozenset[int] | None = None  # ANSWER: acceptable error codes (None: any)
    named_error: int | None = None  # A3: the error the box SHOULD answer
    values: frozenset[int] | None = None  # 26/27: acceptable block values of the answer
    after_error: bool = False  # follows a parse error in the same bytes (R6: resync is a SHOULD)

    @property
    def valid(self) -> bool:
        return self.rule in (Rule.ANSWER, Rule.ANSWER_SHOULD)

    def describe(self) -> str:
        what = f"[{self.clause}] " if self.clause else ""
        return f"{what}{self.message} -> {self.rule.value}"


@dataclass(frozen=True, slots=True)
class Finding:
    verdict: Verdict  # FAIL (a MUST) or NON_STRICT (a SHOULD)
    clause: str
    requirement: str
    observed: str
    key: str = ""  # what failed, for telling distinct failures apart: clause/rule/action

    def describe(self) -> str:
        return f"{self.verdict.value} [{self.clause}] {self.requirement}; the box {self.observed}"


@dataclass
class Judgement:
    findings: list[Finding] = field(default_factory=list)

    @property
    def verdict(self) -> Verdict:
        if any(f.verdict is Verdict.FAIL for f in self.findings):
            return Verdict.FAIL
        return Verdict.NON_STRICT if self.findings else Verdict.PASS

    @property
    def failures(self) -> list[Finding]:
        return [f for f in self.findings if f.verdict is Verdict.FAIL]

    def describe(self) -> str:
        return "; ".join(f.describe() for f in self.findings) or "as PROTOCOL.md allows"


# -- expectations ----------------------------------------------------------------------------


def _frame_expectation(frame: Frame, transport: Transport, extension: bool, profile: Profile) -> Expectation:
    action = int(frame.action)
    desc = frame.describe()
    if frame.action in EXTENSION_ACTIONS and not extension:
        return Expectation(Rule.NOT_REQUEST, "A5", action, f"{desc}: action {action:02X} without extension E")
    if frame.error_code:
        return Expectation(Rule.ANY, "", action, f"{desc}: non-zero error field in a request (PROTOCOL.md is silent)")
    if transport is Transport.TCP and frame.check:
        return Expectation(Rule.ANSWER_SHOULD, "F6", action, f"{desc} with a CRC in its TCP check field",
                           ok_errors=frozenset({0}))
    if not profile.strict and _non_finite(frame):
        return Expectation(Rule.ANY, "B4", action, f"{desc} with NaN/infinity (lenient profile)")
    if frame.action is Action.PROG_IDX:
        value = frame.blocks[0].value  # type: ignore[union-attr]
        return Expectation(Rule.ANSWER, "", action, desc, ok_errors=frozenset({0, CONFLICT}),
                           values=frozenset({value, CONFLICT}))
    if frame.action is Action.VISION_RESULT:
        return Expectation(Rule.ANSWER, "", action, desc, values=frozenset(SENDABLE_RESULTS))
    if frame.action in (Action.CYCLE_ON, Action.CYCLE_OFF):
        # S2/S3: 0001 (not ready), 0002 (CycleOff failed), and either twice MAY be an error
        return Expectation(Rule.ANSWER, "", action, desc)
    return Expectation(Rule.ANSWER, "", action, desc, ok_errors=frozenset({0}))


def _non_finite(frame: Frame) -> bool:
    for block in frame.blocks:
        if isinstance(block, ValueBlock):
            return False
        values = (block.tolerance,) if isinstance(block, ToleranceBlock) else block.pose
        if not all(isfinite(v) for v in values):
            return True
    return False


def request_action(error: ProtocolError) -> int | None:
    """The action of a readable robot→box request header, else None."""
    h = error.header
    if h is None or h.start_word != 0xFEFE or h.version != 1 or h.transfer_type != TransferType.ROBOT_TO_BOX:
        return None
    return h.action


def _error_expectation(error: ProtocolError, transport: Transport, extension: bool, profile: Profile) -> Expectation:
    clause = error.clause
    action = request_action(error)
    msg = error.message
    if transport is Transport.UDP and clause in ("F7", "F5"):
        return Expectation(Rule.DROP, clause, action, msg)
    if isinstance(error, _NOT_REQUEST) or action is None:
        return Expectation(Rule.NOT_REQUEST, clause, action, msg)
    if action in EXTENSION_ACTIONS and not extension:
        return Expectation(Rule.NOT_REQUEST, "A5", action, f"{msg} (action {action:02X} without extension E)")
    named = _ACTION_ERROR.get(action)
    if clause == "F6":
        return Expectation(Rule.ANY, clause, action, f"{msg} (a TCP receiver SHOULD ignore the check field)")
    if isinstance(error, FloatError):
        if not profile.strict:
            return Expectation(Rule.ANY, clause, action, msg)
        return Expectation(Rule.REJECT_SHOULD, clause, action, msg, named_error=named)
    return Expectation(Rule.REJECT, clause, action, msg, named_error=named if clause in _SHAPE_CLAUSES else None)


def _completion(decoder: StreamDecoder) -> int:
    """Zero bytes that complete the partial frame the decoder holds (at least one)."""
    buffered = decoder.buffered
    if buffered < HEADER_LEN:
        return HEADER_LEN - buffered
    tail = decoder._buf[decoder._pos : decoder._pos + HEADER_LEN]  # noqa: SLF001 - the header it waits on
    order = "big" if decoder.profile.byte_order == "big" else "little"
    total = HEADER_LEN + tail[7] * int.from_bytes(tail[8:10], order) + 2  # type: ignore[arg-type]
    return max(1, total - buffered)


def expectations(
    data: bytes,
    profile: Profile,
    transport: Transport = Transport.TCP,
    extension: bool = True,
    eof: bool = False,
) -> tuple[bytes, tuple[Expectation, ...]]:
    """(filler, one expectation per event) for ``data`` sent to a box.

    TCP: the stream decoder's events; ``eof`` ends the stream after ``data`` (a
    truncated frame then is an F5 error), else a frame left incomplete is completed
    with zero filler bytes (returned; send them after ``data``). UDP: ``data`` is one
    datagram (F7, R7)."""
    if transport is Transport.UDP:
        try:
            events: list[Frame | ProtocolError] = [decode_datagram(data, profile, TransferType.ROBOT_TO_BOX)]
        except ProtocolError as exc:
            events = [exc]
        filler = b""
    else:
        decoder = StreamDecoder(profile, TransferType.ROBOT_TO_BOX)
        events = decoder.feed(data)
        filler = b""
        if eof:
            decoder.receive_data(b"")
            events += list(decoder.events())
        else:
            for _ in range(8):  # a header, then its body: two rounds suffice; bounded anyway
                if not decoder.buffered:
                    break
                more = bytes(_completion(decoder))
                filler += more
                events += decoder.feed(more)
    out: list[Expectation] = []
    seen_error = False
    for event in events:
        if isinstance(event, Frame):
            exp = _frame_expectation(event, transport, extension, profile)
        else:
            exp = _error_expectation(event, transport, extension, profile)
        if seen_error:
            exp = Expectation(exp.rule, exp.clause, exp.action, exp.message, exp.ok_errors, exp.named_error,
                              exp.values, after_error=True)
        seen_error = seen_error or not exp.valid
        out.append(exp)
    return filler, tuple(out)


# -- judging -----------------------------------------------------------------------------------

@dataclass(frozen=True, slots=True)
class _Seen:
    """An answer-like outcome reduced to what the oracle needs."""

    action: int | None
    error: int | None
    value: int | None
    outcome: Outcome
    problem: ProtocolError | None  # the box's answer breaks F/A2/E3 (not A4 content)


def _seen(outcome: Outcome, profile: Profile) -> _Seen:
    if isinstance(outcome, Answer):
        f = outcome.frame
        value = getattr(f.blocks[0], "value", None) if f.blocks else None
        return _Seen(int(f.action), f.error_code, value, outcome, None)
    assert isinstance(outcome, Malformed)
    err = outcome.error
    h = err.header
    if h is None or h.start_word != 0xFEFE:
        return _Seen(None, None, None, outcome, err)
    value = None
    raw = err.raw
    if h.block_type == 3 and h.block_count >= 1 and len(raw) >= HEADER_LEN + 5:
        order = ">" if profile.float_byte_order == "big" else "<"
        value = struct.unpack_from(order + "i", raw, HEADER_LEN + 1)[0]
    problem = None if isinstance(err, AnswerError) and err.clause == "A4" else err
    return _Seen(h.action, h.error_code, value, outcome, problem)


def _fail(clause: str, requirement: str, observed: str, key: str = "") -> Finding:
    return Finding(Verdict.FAIL, clause, requirement, observed, key or clause)


def _should(clause: str, requirement: str, observed: str, key: str = "") -> Finding:
    return Finding(Verdict.NON_STRICT, clause, requirement, observed, key or clause)


_KNOWN_ACTIONS = frozenset(int(a) for a in Action)


def _key(exp: Expectation, what: str) -> str:
    """clause/rule/action/what: one key per way of failing (any unknown action is one action)."""
    action = f"{exp.action:02X}" if exp.action in _KNOWN_ACTIONS else "-"
    return f"{exp.clause or 'valid'}/{exp.rule.value}/{action}/{what}"


def _judge_answer(exp: Expectation, seen: _Seen, out: list[Finding]) -> None:
    what = seen.outcome.describe()
    err = seen.error
    rule = exp.rule
    if rule is Rule.ANSWER:
        if exp.ok_errors is not None and err not in exp.ok_errors:
            codes = " or ".join(f"{c:04X}" for c in sorted(exp.ok_errors))
            out.append(_fail("A1", f"A1/A3: a well-formed request ({exp.message}) is answered {codes}", what,
                             _key(exp, "code")))
        elif exp.values is not None and seen.value not in exp.values:
            clause = "E2" if exp.action == Action.PROG_IDX else "E3"
            allowed = ", ".join(str(v) for v in sorted(exp.values))
            out.append(_fail(clause, f"{clause}: the answer to {exp.message} carries {allowed}", what, _key(exp, "value")))
    elif rule is Rule.ANSWER_SHOULD:
        if err != 0:
            out.append(_should(exp.clause, f"F6: a TCP receiver SHOULD accept a correct CRC ({exp.message})", what,
                               _key(exp, "code")))
    elif rule in (Rule.REJECT, Rule.NOT_REQUEST, Rule.DROP):
        if err == 0 and not (exp.action in EXTENSION_ACTIONS and seen.value == NOT_UNDERSTOOD):
            req = {Rule.REJECT: "A3/R1: a request that is a parse error MUST NOT be answered 0000",
                   Rule.NOT_REQUEST: "A5/R1: a frame that is not a request MUST NOT be answered 0000",
                   Rule.DROP: "R7: a datagram with a wrong CRC or length MUST NOT be answered 0000"}[rule]
            out.append(_fail(exp.clause, f"{req} ({exp.message})", what, _key(exp, "0000")))
        elif rule is Rule.DROP:
            out.append(_should("R7", f"R7: such a datagram SHOULD be dropped silently ({exp.message})", what,
                               _key(exp, "answered")))
        elif exp.named_error is not None and err != exp.named_error:
            out.append(_should("A3", f"A3: a {exp.clause} parse error SHOULD be answered {exp.named_error:04X} "
                                     f"({exp.message})", what, _key(exp, "code")))
    elif rule is Rule.REJECT_SHOULD:
        if err == 0:
            out.append(_should("B4", f"B4: NaN or infinity SHOULD be treated as a parse error ({exp.message})", what,
                               _key(exp, "0000")))
        elif exp.named_error is not None and err != exp.named_error:
            out.append(_should("A3", f"A3: a B4 parse error SHOULD be answered {exp.named_error:04X}", what,
                               _key(exp, "code")))


def _judge_unanswered(exp: Expectation, how: str, out: list[Finding], closed: bool = False) -> None:
    """No answer came for ``exp`` (the box went on to the probe, closed, or hung)."""
    if exp.rule is Rule.ANSWER:
        if exp.after_error and closed:
            return  # R6: after garbage the box may close the connection instead of resynchronising
        if exp.after_error:
            out.append(_should("R6", f"R6: after bytes that are not a frame the box SHOULD resynchronise on the "
                                      f"next valid frame ({exp.message} got no answer)", how, _key(exp, "resync")))
        else:
            out.append(_fail("A1", f"A1: a well-formed request ({exp.message}) is answered", how,
                             _key(exp, "unanswered")))
    elif exp.rule is Rule.ANSWER_SHOULD:
        out.append(_should(exp.clause, f"F6: a TCP receiver SHOULD accept a correct CRC ({exp.message})", how,
                           _key(exp, "unanswered")))
    elif exp.rule in (Rule.REJECT, Rule.REJECT_SHOULD) and exp.named_error is not None:
        out.append(_should("A3", f"A3: a {exp.clause} parse error SHOULD be answered {exp.named_error:04X} "
                                 f"({exp.message})", how, _key(exp, "unanswered")))


def judge(
    expects: Sequence[Expectation],
    outcomes: Sequence[Outcome],
    end: Outcome | None,
    profile: Profile,
    probe_action: int | None = None,
) -> Judgement:
    """Judge what the box did with the bytes of ``expects``.

    ``outcomes``: the answers (and malformed answers) that came before the probe's
    answer, in order. ``end``: the probe's answer, or Closed / Silence when the
    exchange ended otherwise (None: the probe was answered and it is not judged)."""
    out: list[Finding] = []
    j = 0
    rejects = [e for e in expects if not e.valid]
    for outcome in outcomes:
        if not isinstance(outcome, (Answer, Malformed)):
            continue
        seen = _seen(outcome, profile)
        if seen.problem is not None and (seen.action is None or seen.problem.clause != "A4"):
            out.append(_fail(seen.problem.clause, f"{seen.problem.clause}: the box's answers are conforming frames",
                             outcome.describe(), f"answer/{seen.problem.clause}"))
            if seen.action is None:
                continue
        k = next((k for k in range(j, len(expects)) if expects[k].action == seen.action), None)
        if k is None:  # an answer to something no event asked for (garbage, or a second answer)
            if seen.error == 0:
                clause = rejects[0].clause if rejects else "A1"
                req = ("R1: the box never answers 0000 to bytes that break F, B or A5" if rejects
                       else "A1: exactly one answer per request")
                out.append(_fail(clause, req, f"{outcome.describe()} (an answer no request of these bytes asked for)",
                                 f"{clause}/unasked/0000"))
            elif not rejects:
                out.append(_fail("A1", "A1: exactly one answer per request",
                                 f"{outcome.describe()} (an answer no request of these bytes asked for)", "A1/unasked"))
            continue
        for skipped in expects[j:k]:
            _judge_unanswered(skipped, f"answered the next request instead ({outcome.describe()})", out)
        _judge_answer(expects[k], seen, out)
        j = k + 1
    if isinstance(end, Answer) and probe_action is not None:
        how = "went on to answer the probe"
        if end.frame.error_code != 0:
            out.append(_fail("A1", "A1/A4/S3: the valid probe request behind the bytes is answered 0000",
                             end.describe(), "probe/code"))
    elif isinstance(end, Closed):
        how = end.describe()
        if not rejects:
            out.append(_fail("A1", "A1: the box answers well-formed requests (it may close only after bytes that "
                                   "are not a request, A5/R6)", how, "end/closed"))
    elif isinstance(end, Silence):
        how = f"{end.describe()} (nothing more came, not even the probe's answer)"
        if probe_action is not None:
            if rejects:
                out.append(_should("R6", "R6: after bytes that are not a frame the box SHOULD resynchronise or "
                                         "close; hanging silently is NON-STRICT", how, "end/hang"))
            else:
                out.append(_fail("T1", "A1/T1: every well-formed request is answered within time_out", how,
                                 "end/silence"))
    else:
        how = "went on"
    for rest in expects[j:]:
        _judge_unanswered(rest, how, out, closed=isinstance(end, Closed))
    return Judgement(out)

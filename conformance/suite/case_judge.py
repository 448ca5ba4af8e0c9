"""Expectations as *sets of acceptable outcomes*, and the verdicts cases raise.

A case never states more than PROTOCOL.md: it lists what a conforming box may do
(e.g. "answered 1001, or closed the connection") and, separately, what a box
SHOULD do. :func:`check` turns an outcome that matches none of them into the
verdict of the requirement's level, with expected, observed and the bytes.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from typing import Any

from ..harness.client import Answer, Closed, Malformed, Outcome, Silence
from ..model.case_verdicts import CaseVerdict, Inconclusive, Skip  # noqa: F401 - the judging routine's verdicts too
from ..model.signature import Reply, Sig, Signature
from ..model.verdicts import Level, Verdict, broken_verdict
from ..protocol import (
    DEFAULT_PROFILE,
    Action,
    ErrorCode,
    Frame,
    Profile,
    ProtocolError,
    TransferType,
    ValueBlock,
    codec_for,
    header_field_bytes,
)
from ..protocol.answers import Cycle, allowed_codes, allowed_values
from ..protocol.constants import START_WORD
from .record import Expect, ExpectSpec, Requirement


def _err(code: int) -> str:
    try:
        return f"{code:#06x} ({ErrorCode(code).name})"
    except ValueError:
        return f"{code:#06x}"


def answered(action: int | None = None, errors: Iterable[int] | None = None, values: Iterable[int] | None = None) -> Expect:
    """An answer echoing ``action`` with an error code in ``errors`` (and block value in ``values``)."""
    errs = None if errors is None else frozenset(errors)
    vals = None if values is None else frozenset(values)
    text = "answered"
    if action is not None:
        text += f" {Action(action).name}"
    if errs is not None:
        text += " with error " + " or ".join(_err(e) for e in sorted(errs))
    if vals is not None:
        text += " carrying value " + " or ".join(str(v) for v in sorted(vals))

    def match(o: Outcome) -> bool:
        if not isinstance(o, Answer):
            return False
        f = o.frame
        if action is not None and f.action != action:
            return False
        if errs is not None and f.error_code not in errs:
            return False
        return not (vals is not None and (not f.blocks or getattr(f.blocks[0], "value", None) not in vals))

    return Expect(text, match, action)


def answered_allowed(action: int, cycle: Cycle = Cycle.UNKNOWN, request: Frame | None = None) -> Expect:
    """What a conforming box may answer a well-formed ``action`` request in ``cycle``: the error codes
    of the answer table (:mod:`conformance.protocol.answers`; any code where it allows any) and, for
    the ``request`` given, the block values (E2/E3)."""
    return answered(action, allowed_codes(action, cycle), None if request is None else allowed_values(request))


def answered_error(action: int | None = None) -> Expect:
    """Answered with any non-zero error code (never 0000)."""
    text = "answered with a non-zero error" + (f" to {Action(action).name}" if action is not None else "")
    return Expect(
        text,
        lambda o: isinstance(o, Answer) and o.frame.error_code != 0 and (action is None or o.frame.action == action),
        action,
    )


SILENCE = Expect("stayed silent", lambda o: isinstance(o, Silence))
CLOSED = Expect("closed or reset the connection", lambda o: isinstance(o, Closed))
def answered_zero(outcome: Outcome) -> bool:
    """The box answered 0000: a well-formed answer, or a frame-like one that does not
    parse (e.g. it echoes an unknown action) but carries error 0000 (the robot reads it)."""
    if isinstance(outcome, Answer):
        return outcome.frame.error_code == 0
    header = outcome.error.header if isinstance(outcome, Malformed) else None
    return header is not None and header.start_word == START_WORD and header.error_code == 0


#: A5/R1: what a box may do with a frame that is not a request: anything but 0000.
NOT_OK = Expect("did not answer 0000 (silence, a non-zero error, or a close)", lambda o: not answered_zero(o))
NOT_MALFORMED = Expect("sent no malformed bytes", lambda o: not isinstance(o, Malformed))


def check(
    outcome: Outcome,
    acceptable: Expect | Iterable[Expect],
    level: Level,
    requirement: str,
    *,
    sent: bytes = b"",
    judged: tuple[str, ...] = (),
    profile: Profile = DEFAULT_PROFILE,
) -> None:
    """Raise the level's verdict unless ``outcome`` is one of the ``acceptable`` ones (judging ``judged``).

    A malformed answer that would be acceptable if it were a conforming frame fails on
    its format alone: FAIL, judging the clause the answer breaks (F1-F6, A2, ...), not
    the requirement of the case."""
    options = [acceptable] if isinstance(acceptable, Expect) else list(acceptable)
    if any(e.matches(outcome) for e in options):
        return
    expected = "; or ".join(e.text for e in options)
    received = outcome.raw
    observed = outcome.describe()
    view = answer_view(outcome, profile) if isinstance(outcome, Malformed) else None
    if isinstance(outcome, Malformed) and view is not None and any(e.matches(view) for e in options):
        error = outcome.error
        raise CaseVerdict(
            Verdict.FAIL,
            f"{error.clause}: the box's answer is not a conforming frame ({error.message}); read leniently it would "
            f"meet \"{requirement}\"",
            requirement=f"{error.clause}: the box's answers are conforming frames",
            expected=expected, observed=observed, sent=sent, received=received,
            judged=(error.clause,), signature=answer_signature(error, _asked(options)),
        )
    raise CaseVerdict(
        broken_verdict(level),
        f"{requirement}: expected {expected}; the box {observed}",
        requirement=requirement,
        expected=expected,
        observed=observed,
        sent=sent,
        received=received,
        judged=judged,
        signature=outcome_signature(outcome, options),
    )


def answer_view(outcome: Malformed, profile: Profile = DEFAULT_PROFILE) -> Answer | None:
    """A malformed answer read leniently: its header's action, error code and first
    type-03 value as a conforming answer would carry them (the value in the profile's
    float_byte_order, as the codec reads it; None when it has no readable header or an
    unknown action)."""
    header = outcome.error.header
    if header is None or header.start_word != START_WORD:
        return None
    try:
        action = Action(header.action)
    except ValueError:
        return None
    raw = outcome.raw
    blocks: tuple[ValueBlock, ...] = ()
    if header.block_type == 3 and header.block_count >= 1 and len(raw) >= 17:
        index, value = codec_for(profile).value.unpack_from(raw, 12)  # the codec's layout of a type-03 block
        blocks = (ValueBlock(index, value),)
    return Answer(Frame(TransferType.BOX_TO_ROBOT, action, blocks, header.error_code), outcome.latency_s, raw)


def _asked(options: list[Expect]) -> int | None:
    return next((int(e.action) for e in options if e.action is not None), None)


def answer_signature(error: ProtocolError, asked: int | None = None) -> Signature:
    """What is wrong with a malformed answer, the same for every answer malformed the same way."""
    h, raw, clause = error.header, error.raw, error.clause
    if h is None:
        return Signature(Sig.ANSWER, clause=clause, field="not-a-frame")
    field, value = {
        "F1": ("start", header_field_bytes(raw, "start_word").hex()),
        "F2": ("version", f"{h.version:04x}"),
        "F3": ("transfer-type", f"{h.transfer_type:02x}"),
        "F6": ("check", raw[-2:].hex() if len(raw) >= 14 else ""),
        "F5": ("length", ""),
        "A4": ("none-error", f"{h.error_code:04x}"),
    }.get(clause, ("shape", f"{h.block_type:02x}/{h.block_count}/{h.block_length}"))
    reply = Reply(asked, h.action, h.error_code, h.transfer_type) if h.start_word == START_WORD else None
    return Signature(Sig.ANSWER, clause=clause, field=field, value=value, reply=reply)


def outcome_signature(outcome: Outcome, options: list[Expect]) -> Signature:
    """What the box did instead of an acceptable outcome, for grouping like failures."""
    asked = _asked(options)
    name = _action_name(asked)
    if isinstance(outcome, Silence):
        return Signature(Sig.SKIPPED if outcome.skipped else Sig.SILENCE, name)
    if isinstance(outcome, Closed):
        return Signature(Sig.CLOSED, name)
    if isinstance(outcome, Malformed):
        return answer_signature(outcome.error, asked)
    f = outcome.frame
    code = f.error_code
    reply = Reply(asked, int(f.action), code, int(f.transfer_type))
    swapped = ((code & 0xFF) << 8) | (code >> 8)
    wanted = [e for e in options if e.action is not None]
    if wanted and code and swapped != code and any(e.matches(_with_code(outcome, swapped)) for e in wanted):
        return Signature(Sig.SWAPPED, "error-code", reply=reply)
    return Signature(Sig.CODE, _action_name(int(f.action)), value=f"{code:04x}", reply=reply)


def reply_signature(outcome: Outcome, asked: int) -> Signature:
    """The signature of ``outcome`` as the answer to an ``asked`` request a case judged by its own logic
    (with the answer's fields, for the root causes read across every answer)."""
    return outcome_signature(outcome, [Expect(f"answered {_action_name(asked)}", lambda o: False, int(asked))])


def _with_code(outcome: Answer, code: int) -> Answer:
    f = outcome.frame
    return Answer(Frame(f.transfer_type, f.action, f.blocks, code), outcome.latency_s, outcome.raw)


def _action_name(action: int | None) -> str:
    if action is None:
        return "-"
    try:
        return Action(action).name
    except ValueError:
        return f"{action:02X}"


def fail(level: Level, requirement: str, expected: str, observed: str, sent: bytes = b"", received: bytes = b"",
         signature: Signature | None = None, judged: tuple[str, ...] = ()) -> CaseVerdict:
    """A verdict for a requirement judged by the case's own logic (return it and raise)."""
    return CaseVerdict(
        broken_verdict(level),
        f"{requirement}: expected {expected}; observed {observed}",
        requirement=requirement,
        expected=expected,
        observed=observed,
        sent=sent,
        received=received,
        signature=signature,
        judged=judged,
    )


# -- the one judging routine -----------------------------------------------------------------------


def resolve(spec: ExpectSpec | None, values: Mapping[str, Any]) -> Expect | None:
    """An Expect, or the one a function of the case's values returns."""
    if spec is None or isinstance(spec, Expect):
        return spec
    return spec(**values)


def words(text: str, values: Mapping[str, Any]) -> str:
    """A requirement's words with the case's values filled in (``{action}`` ...)."""
    try:
        return text.format(**values)
    except (KeyError, IndexError, ValueError):
        return text


def judge(outcome: Outcome, requirement: Requirement, level: Level, values: Mapping[str, Any] | None = None, *,
          sent: bytes = b"", profile: Profile = DEFAULT_PROFILE) -> str | None:
    """Turn ``outcome`` into the requirement's verdict: raise it unless PASS.

    First the outcomes that leave it unjudgeable (INCONCLUSIVE), then the acceptable ones
    (else the level's broken verdict: FAIL for a MUST), then what a conforming box SHOULD
    do (else NON-STRICT). Returns the words to record when the outcome is an acceptable one
    worth recording (the requirement's ``informational``), else None."""
    if all(x is None for x in (requirement.accept, requirement.should, requirement.inconclusive,
                               requirement.informational)):  # judged by nothing: it could never fail
        raise ValueError(f"requirement {requirement.text[:80]!r} names no outcome to judge by: the case is misdeclared")
    values = dict(values or {})
    clauses = judged_clauses(requirement, values)
    unjudgeable = resolve(requirement.inconclusive, values)
    if unjudgeable is not None and unjudgeable.matches(outcome):
        why = words(requirement.inconclusive_text, values) or requirement.words(words(requirement.text, values))
        raise Inconclusive(f"{why} (the box {outcome.describe()})", judged=clauses)
    accept = resolve(requirement.accept, values)
    if accept is not None:
        check(outcome, accept, requirement.level or level, requirement.words(words(requirement.text, values)),
              sent=sent, judged=clauses, profile=profile)
    should = resolve(requirement.should, values)
    if should is not None:
        named = requirement.should_clauses or clauses
        text = words(requirement.should_text or requirement.text, values)
        check(outcome, should, Level.SHOULD, requirement.words(text, requirement.should_clauses), sent=sent,
              judged=named, profile=profile)
    note = resolve(requirement.informational, values)
    if note is not None and note.matches(outcome):
        return f"{words(requirement.informational_text, {**values, 'outcome': outcome.describe()})}"
    return None


def broken(requirement: Requirement, level: Level, expected: str, observed: str, values: Mapping[str, Any] | None = None,
           *, sent: bytes = b"", received: bytes = b"", signature: Signature | None = None) -> CaseVerdict:
    """The verdict for a requirement judged by the case's own logic (raise it)."""
    values = dict(values or {})
    clauses = judged_clauses(requirement, values)
    return fail(requirement.level or level, requirement.words(words(requirement.text, values)), expected,
                observed, sent, received, signature, clauses)


def judged_clauses(requirement: Requirement, values: Mapping[str, Any]) -> tuple[str, ...]:
    """The clauses a verdict of ``requirement`` judges: its own, or those its ``judged_from`` value holds."""
    if requirement.clauses or not requirement.judged_from:
        return requirement.clauses
    return tuple(str(c) for c in values.get(requirement.judged_from, ()))

"""Expectations as *sets of acceptable outcomes*, and the verdicts cases raise.

A case never states more than PROTOCOL.md: it lists what a conforming box may do
(e.g. "answered 1001, or closed the connection") and, separately, what a box
SHOULD do. :func:`check` turns an outcome that matches none of them into the
verdict of the requirement's level, with expected, observed and the bytes.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from dataclasses import dataclass

from ..harness.client import Answer, Closed, Malformed, Outcome, Silence
from ..protocol import Action, ErrorCode
from .verdicts import Level, Verdict


class CaseVerdict(Exception):
    """Raised by a case to end it with a verdict other than PASS."""

    def __init__(
        self,
        verdict: Verdict,
        message: str,
        *,
        requirement: str = "",
        expected: str = "",
        observed: str = "",
        sent: bytes = b"",
        received: bytes = b"",
    ) -> None:
        super().__init__(message)
        self.verdict = verdict
        self.message = message
        self.requirement = requirement
        self.expected = expected
        self.observed = observed
        self.sent = sent
        self.received = received

    def __str__(self) -> str:
        parts = [f"{self.verdict.value}: {self.message}"]
        if self.requirement:
            parts.append(f"requirement: {self.requirement}")
        if self.expected:
            parts.append(f"expected: {self.expected}")
        if self.observed:
            parts.append(f"observed: {self.observed}")
        if self.sent:
            parts.append(f"sent: {self.sent.hex(' ')}")
        if self.received:
            parts.append(f"received: {self.received.hex(' ')}")
        return "\n".join(parts)


class Inconclusive(CaseVerdict):
    def __init__(self, message: str, **kw: object) -> None:
        super().__init__(Verdict.INCONCLUSIVE, message, **kw)  # type: ignore[arg-type]


class Skip(CaseVerdict):
    def __init__(self, message: str) -> None:
        super().__init__(Verdict.SKIP, message)


@dataclass(frozen=True)
class Expect:
    """One acceptable outcome: a description and a predicate."""

    text: str
    matches: Callable[[Outcome], bool]

    def __or__(self, other: Expect) -> Expect:
        return Expect(f"{self.text}, or {other.text}", lambda o: self.matches(o) or other.matches(o))


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

    return Expect(text, match)


def answered_error(action: int | None = None) -> Expect:
    """Answered with any non-zero error code (never 0000)."""
    text = "answered with a non-zero error" + (f" to {Action(action).name}" if action is not None else "")
    return Expect(
        text,
        lambda o: isinstance(o, Answer) and o.frame.error_code != 0 and (action is None or o.frame.action == action),
    )


SILENCE = Expect("stayed silent", lambda o: isinstance(o, Silence))
CLOSED = Expect("closed or reset the connection", lambda o: isinstance(o, Closed))
def answered_zero(outcome: Outcome) -> bool:
    """The box answered 0000: a well-formed answer, or a frame-like one that does not
    parse (e.g. it echoes an unknown action) but carries error 0000 (the robot reads it)."""
    if isinstance(outcome, Answer):
        return outcome.frame.error_code == 0
    header = outcome.error.header if isinstance(outcome, Malformed) else None
    return header is not None and header.start_word == 0xFEFE and header.error_code == 0


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
) -> None:
    """Raise the level's verdict unless ``outcome`` is one of the ``acceptable`` ones."""
    options = [acceptable] if isinstance(acceptable, Expect) else list(acceptable)
    if any(e.matches(outcome) for e in options):
        return
    expected = "; or ".join(e.text for e in options)
    received = outcome.raw
    observed = outcome.describe()
    raise CaseVerdict(
        level.broken_verdict,
        f"{requirement}: expected {expected}; the box {observed}",
        requirement=requirement,
        expected=expected,
        observed=observed,
        sent=sent,
        received=received,
    )


def fail(level: Level, requirement: str, expected: str, observed: str, sent: bytes = b"", received: bytes = b"") -> CaseVerdict:
    """A verdict for a requirement judged by the case's own logic (return it and raise)."""
    return CaseVerdict(
        level.broken_verdict,
        f"{requirement}: expected {expected}; observed {observed}",
        requirement=requirement,
        expected=expected,
        observed=observed,
        sent=sent,
        received=received,
    )

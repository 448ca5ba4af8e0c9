"""The verdicts a case raises to end other than PASS: :class:`CaseVerdict`, :class:`Inconclusive`, :class:`Skip`.

In :mod:`conformance.model` so that the run's state (:mod:`conformance.runtime.run_state`) can raise and read them
without importing the case author's API; a case imports them from :mod:`conformance.suite`.
"""

from __future__ import annotations

from .signature import Signature
from .verdicts import Verdict


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
        judged: tuple[str, ...] = (),
        signature: Signature | None = None,
    ) -> None:
        super().__init__(message)
        self.verdict = verdict
        self.message = message
        self.requirement = requirement
        self.expected = expected
        self.observed = observed
        self.sent = sent
        self.received = received
        #: the clause(s) this verdict judged, as the requirement names them (none: the case's clauses)
        self.judged = judged
        #: what the defect looks like, for grouping verdicts under one root cause
        self.signature = signature

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

"""What a case author needs, in one import: ``from conformance.suite import case, CaseContext, Level, ...``.

The case record (:func:`case`, :class:`Requirement`, :class:`Expect`), the ``isight`` fixture's
:class:`CaseContext`, the judging routine's expectations (:func:`answered`, :data:`NOT_OK`...),
the verdicts a case may raise, the shared requirements (:mod:`.requirements`) and the pose stream.
Helpers of one clause family live in their own module here (``block_requests``, ``session_steps``...).
"""

from __future__ import annotations

from ..model.signature import Sig, Signature
from ..model.verdicts import Level, Verdict
from .case_context import CaseContext, answers_none
from .case_judge import (
    CLOSED,
    NOT_MALFORMED,
    NOT_OK,
    SILENCE,
    CaseVerdict,
    Inconclusive,
    Skip,
    answered,
    answered_allowed,
    answered_error,
    answered_zero,
    check,
    fail,
    reply_signature,
)
from .record import MARKER, Expect, Requirement, case, record
from .requirements import ANSWERED, ANSWERED_0, NOT_0000, NOT_ANSWERED
from .run_state import responsive

__all__ = [
    "ANSWERED", "ANSWERED_0", "CLOSED", "MARKER", "NOT_0000", "NOT_ANSWERED", "NOT_MALFORMED", "NOT_OK", "SILENCE",
    "CaseContext", "CaseVerdict", "Expect", "Inconclusive", "Level", "Requirement", "Sig", "Signature", "Skip",
    "Verdict", "answered", "answered_allowed", "answered_error", "answered_zero", "answers_none", "case", "check",
    "fail", "record", "reply_signature", "responsive",
]

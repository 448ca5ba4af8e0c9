"""What a case author needs, in one import: ``from conformance.suite import case, CaseContext, Level, ...``.

The case record (:func:`case`, :class:`Requirement`, :class:`Expect`), the ``isight`` fixture's
:class:`CaseContext`, the judging routine's expectations (:func:`answered`, :data:`NOT_OK`...),
the verdicts a case may raise, the outcomes of an exchange (:class:`Answer`, :class:`Silence`...),
the shared requirements (:mod:`.requirements`), the sequences and the pose stream (:mod:`.sequence`).
Helpers of one clause family live beside its cases, in the family's module of :mod:`conformance.cases`.
"""

from __future__ import annotations

import pytest

from ..harness.client import TcpConnection, UdpChannel
from ..harness.liveness import responsive
from ..harness.outcomes import Answer, Closed, Malformed, Outcome, Silence
from ..harness.target import Unreachable
from ..harness.trajectory import PrimerTrajectory
from ..harness.transcript import Kind
from ..harness.waits import STREAM
from ..model.case_verdicts import CaseVerdict, Inconclusive, Skip
from ..model.signature import Sig, Signature
from ..model.verdicts import Level, Verdict
from ..runtime.profile_options import profile_flags
from ..runtime.run_state import STATE
from ..runtime.settings import SuiteSettings
from .case_context import CaseContext, answers_none
from .case_judge import (
    CLOSED,
    NOT_MALFORMED,
    NOT_OK,
    SILENCE,
    answered,
    answered_allowed,
    answered_error,
    answered_zero,
    check,
    fail,
    reply_signature,
)
from .record import ALONE_MARK, MARKER, Expect, Requirement, case, record, stateless_frame
from .requirements import ANSWERED, ANSWERED_0, NOT_0000, NOT_ANSWERED
from .sequence import (
    DEFAULT_POSE,
    PoseStream,
    Sequence,
    SequenceError,
    latency_figures,
    load,
    percentile,
    pieces_of,
    run_sequence,
    shipped,
)


def run_settings(config: pytest.Config) -> SuiteSettings:
    """The run's resolved settings, for a case module's ``pytest_generate_tests``."""
    return config.stash[STATE].settings


__all__ = [
    "ALONE_MARK", "ANSWERED", "ANSWERED_0", "CLOSED", "DEFAULT_POSE", "MARKER", "NOT_0000", "NOT_ANSWERED",
    "NOT_MALFORMED", "NOT_OK", "SILENCE", "STREAM", "Answer", "CaseContext", "CaseVerdict", "Closed", "Expect",
    "Inconclusive", "Kind", "Level", "Malformed", "Outcome", "PoseStream", "PrimerTrajectory", "Requirement",
    "Sequence", "SequenceError", "Sig", "Signature", "Silence", "Skip", "TcpConnection", "UdpChannel", "Unreachable",
    "Verdict", "answered", "answered_allowed", "answered_error", "answered_zero", "answers_none", "case", "check",
    "fail", "latency_figures", "load", "percentile", "pieces_of", "profile_flags", "record", "reply_signature",
    "responsive", "run_settings", "run_sequence", "shipped", "stateless_frame",
]

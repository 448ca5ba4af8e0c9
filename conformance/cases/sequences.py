"""SEQ: the scripted sequences in vectors/sequences/*.json, and any given with --sequence FILE.

Each shipped file is one case whose ID, clauses, level and title come from the file
(e.g. ``SEQ-S1``). A user's file (``--sequence FILE``) is the case ``<its id>[<file
stem>]``; without any, ``SEQ-USER[none]`` is SKIP. The format is documented in
``vectors/sequences/README.md``; :mod:`conformance.suite.sequence` loads and runs it.
"""

from __future__ import annotations

import pytest

from conformance.suite import CaseContext, Skip
from conformance.suite.sequence import Sequence, run_sequence
from conformance.suite.sequence_cases import shipped_cases, user_sequence_params

globals().update(shipped_cases())  # test_seq_s1, ...: one case per shipped file


def pytest_generate_tests(metafunc: pytest.Metafunc) -> None:
    if metafunc.function is test_user_sequence:
        from conformance.pytest_plugin import STATE

        metafunc.parametrize("sequence", user_sequence_params(metafunc.config.stash[STATE].settings.sequences))


def test_user_sequence(isight: CaseContext, sequence: Sequence | None) -> None:
    if sequence is None:
        raise Skip("no --sequence FILE given")
    run_sequence(isight, sequence)

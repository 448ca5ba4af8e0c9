"""SEQ: the scripted sequences in vectors/sequences/*.json, and any given with --sequence FILE.

Each shipped file is one case whose ID, clauses, level and title come from the file
(e.g. ``SEQ-S1``). A user's file (``--sequence FILE``) is the case ``<its id>[<file
stem>]``; without any, ``SEQ-USER[none]`` is SKIP. The format is documented in
``vectors/sequences/README.md``; :mod:`conformance.suite.sequence` loads and runs it.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

from conformance.suite import MARKER, CaseContext, Level, Skip, record
from conformance.suite.sequence import Sequence, SequenceError, load, run_sequence, shipped

SHIPPED = shipped()


def _case_for(seq: Sequence) -> Callable[[CaseContext], None]:
    @getattr(pytest.mark, MARKER)(seq.record)
    def test(isight: CaseContext) -> None:
        run_sequence(isight, seq)

    test.__name__ = test.__qualname__ = "test_" + seq.id.lower().replace("-", "_")
    test.__doc__ = f"{seq.title} ({seq.path.name})"
    return test


for _seq in SHIPPED:  # one case function per shipped file, built once
    _test = _case_for(_seq)
    globals()[_test.__name__] = _test

_NONE = record("SEQ-USER", ("S1",), Level.MUST, "Sequence files given with --sequence FILE",
               "as each file says; SKIP when no file is given")


def pytest_generate_tests(metafunc: pytest.Metafunc) -> None:
    if metafunc.function is not test_user_sequence:
        return
    from conformance.pytest_plugin import STATE

    shipped_paths = {s.path.resolve() for s in SHIPPED}
    params: list[Any] = []
    for path in metafunc.config.stash[STATE].settings.sequences:
        if Path(path).resolve() in shipped_paths:
            continue  # already a case of its own
        try:
            seq = load(path)
        except SequenceError as exc:
            raise pytest.UsageError(f"--sequence {exc}") from None
        params.append(pytest.param(seq, marks=getattr(pytest.mark, MARKER)(seq.record), id=seq.stem))
    if not params:
        params = [pytest.param(None, marks=getattr(pytest.mark, MARKER)(_NONE), id="none")]
    metafunc.parametrize("sequence", params)


def test_user_sequence(isight: CaseContext, sequence: Sequence | None) -> None:
    if sequence is None:
        raise Skip("no --sequence FILE given")
    run_sequence(isight, sequence)

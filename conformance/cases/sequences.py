"""SEQ: the scripted sequences in vectors/sequences/*.json, and any given with --sequence FILE.

Each shipped file is one case whose ID, clauses, level and title come from the file
(e.g. ``SEQ-S1``). A user's file (``--sequence FILE``) is the case ``<its id>[<file
stem>]``; without any, ``SEQ-USER[none]`` is SKIP. The format is documented in
``vectors/sequences/README.md``; :mod:`conformance.suite.sequence` loads and runs it.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Any

import pytest

from conformance.suite import (
    MARKER,
    CaseContext,
    Level,
    Sequence,
    SequenceError,
    Skip,
    load,
    record,
    run_sequence,
    run_settings,
    shipped,
)

# -- the family's helpers: The SEQ cases (conformance/cases/sequences.py): one case function per shipped sequence file,
SHIPPED = shipped()

#: SEQ-USER when no file is given: SKIP
NO_USER_SEQUENCE = record("SEQ-USER", ("S1",), Level.MUST, "Sequence files given with --sequence FILE",
                          "as each file says; SKIP when no file is given")


def case_for(seq: Sequence) -> Callable[[CaseContext], None]:
    """The case function of one shipped sequence file (its record comes from the file)."""
    @getattr(pytest.mark, MARKER)(seq.record)
    def test(isight: CaseContext) -> None:
        run_sequence(isight, seq)

    test.__name__ = test.__qualname__ = "test_" + seq.id.lower().replace("-", "_")
    test.__doc__ = f"{seq.title} ({seq.path.name})"
    return test


def shipped_cases() -> dict[str, Callable[[CaseContext], None]]:
    """Each shipped file's case function by its name, built once."""
    return {(test := case_for(seq)).__name__: test for seq in SHIPPED}


def user_sequence_params(paths: Iterable[str | Path]) -> list[Any]:
    """SEQ-USER's parameters: one per ``--sequence`` file that is not shipped (a bad file is a usage error)."""
    shipped_paths = {s.path.resolve() for s in SHIPPED}
    params: list[Any] = []
    for path in paths:
        if Path(path).resolve() in shipped_paths:
            continue  # already a case of its own
        try:
            seq = load(path)
        except SequenceError as exc:
            raise pytest.UsageError(f"--sequence {exc}") from None
        params.append(pytest.param(seq, marks=getattr(pytest.mark, MARKER)(seq.record), id=seq.stem))
    return params or [pytest.param(None, marks=getattr(pytest.mark, MARKER)(NO_USER_SEQUENCE), id="none")]


# -- the cases

globals().update(shipped_cases())  # test_seq_s1, ...: one case per shipped file


def pytest_generate_tests(metafunc: pytest.Metafunc) -> None:
    if metafunc.function is test_user_sequence:
        metafunc.parametrize("sequence", user_sequence_params(run_settings(metafunc.config).sequences))


def test_user_sequence(isight: CaseContext, sequence: Sequence | None) -> None:
    if sequence is None:
        raise Skip("no --sequence FILE given")
    run_sequence(isight, sequence)

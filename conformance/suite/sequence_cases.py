"""The SEQ cases (conformance/cases/sequences.py): one case function per shipped sequence file,
and the parameters of ``SEQ-USER`` (the files given with ``--sequence FILE``)."""

from __future__ import annotations

from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Any

import pytest

from ..model.verdicts import Level
from .case_context import CaseContext
from .record import MARKER, record
from .sequence import Sequence, SequenceError, load, run_sequence, shipped

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

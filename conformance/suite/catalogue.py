"""Case metadata: every case has a stable ID, its clauses, its level, a title and
its expectation in words. The ``case`` decorator attaches them as a pytest marker;
the catalogue (``--list``, README, reports) is generated from the markers."""

from __future__ import annotations

import re
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, TypeVar

import pytest

from ..protocol.clauses import clause_ids
from .verdicts import Level

F = TypeVar("F", bound=Callable[..., Any])
MARKER = "isight_case"
_ID = re.compile(r"^[A-Z][0-9]?-[0-9]{2}[a-z]?$|^[A-Z]+-[A-Z0-9-]+$")
_CLAUSE = re.compile("^(" + "|".join(sorted(clause_ids())) + ")$")  # the clause registry's ids


@dataclass(frozen=True)
class CaseInfo:
    id: str
    clauses: tuple[str, ...]
    level: Level
    title: str
    expect: str  # the set of acceptable outcomes, in words
    needs: tuple[str, ...] = ()  # "udp", "extension", "liveness" ...

    @property
    def family(self) -> str:
        return self.clauses[0][0]


def case(id: str, clauses: list[str] | tuple[str, ...], level: Level | str, title: str, expect: str,
         needs: tuple[str, ...] = ()) -> Callable[[F], F]:
    """Mark a test function as conformance case ``id``."""
    if not _ID.match(id):
        raise ValueError(f"case id {id!r} must look like 'F1-01' or 'SEQ-S1'")
    bad = [c for c in clauses if not _CLAUSE.match(c)]
    if bad or not clauses:
        raise ValueError(f"case {id}: unknown clause IDs {bad or clauses}")
    info = CaseInfo(id, tuple(clauses), Level(level), title, expect, tuple(needs))

    def deco(fn: F) -> F:
        return pytest.mark.isight_case(info)(fn)  # type: ignore[no-any-return]

    return deco


def info_of(item: pytest.Item) -> CaseInfo | None:
    marker = item.get_closest_marker(MARKER)
    if marker is None:
        return None
    info: CaseInfo = marker.args[0]
    param = getattr(item, "callspec", None)
    if param is not None and param.id:
        return CaseInfo(f"{info.id}[{param.id}]", info.clauses, info.level, info.title, info.expect, info.needs)
    return info

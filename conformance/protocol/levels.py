"""The requirement levels of RFC 2119 as PROTOCOL.md uses them: one vocabulary for the
clause registry, the cases' records, the verdicts and the findings (sans-I/O)."""

from __future__ import annotations

import enum


class Level(str, enum.Enum):
    """MUST, SHOULD or MAY, strongest first (``list(Level)`` is in that order)."""

    MUST = "MUST"
    SHOULD = "SHOULD"
    MAY = "MAY"

    def __str__(self) -> str:  # f-strings and joins print the word, on every Python
        return self.value

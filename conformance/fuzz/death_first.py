"""Death first: a failure that left the box dead is reported as R2, and R2 is printed before anything else.

When a well-formed request is met by a close, a reset or silence, the box may have
*died*: then what a user needs to read first is "R2: the box crashed", not the rudeness
(A1) that the crash looked like from the open connection. The session machine checks
the box's liveness (a fresh connection answering NONE) before it reports any failure;
when the box is dead, :func:`died` turns the trigger's finding into an R2 finding that
keeps the trigger's clause, and :func:`deaths_first` orders a campaign's failures so
that deaths are printed first.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TypeVar

from ..harness.client import Outcome
from ..model.verdicts import Verdict
from .oracle import Finding

#: Finding keys of deaths start with this (``R2/death/<trigger>``).
DEATH_KEY = "R2/death"

REQUIREMENT = "R2: the box stays alive: after any request it still accepts and answers a fresh connection"


def died(trigger: Finding, live: Outcome) -> Finding:
    """The R2 finding for a box found dead right after ``trigger`` (``live``: what the fresh connection got)."""
    clause = trigger.clause if trigger.clause.startswith("R2") else f"R2/{trigger.clause}" if trigger.clause else "R2"
    parts = trigger.key.split("/")
    what = parts[2] if len(parts) > 2 and not trigger.clause.startswith("R2") else "-"  # the trigger's action
    observed = f"died: {trigger.observed}; then a fresh connection {live.describe()} [the trigger: {trigger.requirement}]"
    return Finding(Verdict.FAIL, clause, REQUIREMENT, observed, f"{DEATH_KEY}/session/{what}")


def known_death(death: Finding, known: set[str]) -> bool:
    """Reported before: the same trigger, or (no trigger: the box was found dead at a session's end or at a
    connect) any session death (the session that killed it was reported)."""
    if death.key in known:
        return True
    return death.key.endswith("/-") and any(k.startswith(f"{DEATH_KEY}/session/") for k in known)


def is_death(keys: Sequence[str], kind: str = "") -> bool:
    """A failure whose finding is a death (R2)."""
    return kind == "death" or any(k.startswith(DEATH_KEY) for k in keys)


T = TypeVar("T")


def deaths_first(failures: Sequence[T]) -> list[T]:
    """Deaths (R2) first, the rest after, each in the order found (objects with ``kind`` and ``keys``)."""
    dead = [f for f in failures if is_death(getattr(f, "keys", ()), getattr(f, "kind", ""))]
    return dead + [f for f in failures if f not in dead]


__all__ = ["DEATH_KEY", "REQUIREMENT", "deaths_first", "died", "is_death", "known_death"]

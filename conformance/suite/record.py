"""The one case record: what a case is and what it expects, as data.

Every case of the suite (``@case``), every check of ``certify-robot`` and every scripted
sequence is a :class:`CaseRecord`: a stable ID, its clauses, its level, a title, its
acceptable outcomes in words, and its *requirements* as data (like Autobahn's
``expected[...]`` and h2spec's ``Requirement``): for each thing the case judges, the
requirement's words, the outcomes that meet it, those a conforming box SHOULD show, and
those that make it unjudgeable. One routine (:func:`conformance.suite.case_judge.judge`)
turns an outcome into a verdict; a case body only sends, collects and names what it
judges (``isight.judge(outcome, "answer")``), never restating a level or the words.

The ``case`` decorator attaches the record as a pytest marker; the catalogue (``--list``,
docs/CATALOGUE.md, reports) is generated from the markers.
"""

from __future__ import annotations

import re
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field, replace
from types import MappingProxyType
from typing import Any, TypeVar

import pytest

from ..harness.client import Outcome
from ..model.verdicts import Level
from ..protocol import Action, peek_header
from ..protocol.clauses import clause_ids

F = TypeVar("F", bound=Callable[..., Any])
MARKER = "isight_case"
_ID = re.compile(r"^[A-Z][0-9]?-[0-9]{2}[a-z]?$|^[A-Z]+-[A-Za-z0-9-]+$")
CLAUSE_ID = re.compile("^(" + "|".join(sorted(clause_ids())) + ")$")  # the clause registry's ids

@dataclass(frozen=True)
class Expect:
    """One acceptable outcome: a description and a predicate (and the action it expects answered)."""

    text: str
    matches: Callable[[Outcome], bool]
    action: int | None = None

    def __or__(self, other: Expect) -> Expect:
        action = self.action if self.action is not None else other.action
        return Expect(f"{self.text}, or {other.text}", lambda o: self.matches(o) or other.matches(o), action)


#: An acceptable set of outcomes: an Expect, or a function of the case's values returning one.
ExpectSpec = Expect | Callable[..., Expect | None]


@dataclass(frozen=True)
class Requirement:
    """One thing a case judges: the clauses it judges, the words and the outcomes, as data.

    ``clauses`` name what a verdict of this requirement judged (checked against the registry
    when the requirement is made, at import); the verdict's words are the clauses and the
    ``text``: ``Requirement(("A3",), "a {action} request with {what} MUST NOT be answered 0000")``
    reads "A3: a POSE request with ... MUST NOT be answered 0000". ``text`` (and
    ``should_text``, ``inconclusive_text``) may name the case's values in braces: the case's
    parameters and what the body passes to ``judge``. ``accept``, ``should`` and
    ``inconclusive`` are Expects, or functions of those values returning one. No clauses
    (``()``): the case's own, or those a value named by ``judged_from`` holds when judged
    (a fuzz finding's).
    """

    clauses: tuple[str, ...]
    text: str
    accept: ExpectSpec | None = None  # the acceptable outcomes; else the level's broken verdict
    level: Level | None = None  # None: the case's level
    should: ExpectSpec | None = None  # what a conforming box SHOULD do; else NON-STRICT
    should_text: str = ""
    should_clauses: tuple[str, ...] = ()  # what the SHOULD judges (default: ``clauses``)
    inconclusive: ExpectSpec | None = None  # outcomes that leave the requirement unjudgeable (checked first)
    inconclusive_text: str = ""
    informational: ExpectSpec | None = None  # acceptable outcomes worth recording (INFORMATIONAL, never failing)
    informational_text: str = ""
    judged_from: str = ""  # the name of a value holding the clauses judged, when they are known only then

    def __post_init__(self) -> None:
        bad = [c for c in (*self.clauses, *self.should_clauses) if not CLAUSE_ID.match(c)]
        if bad:
            raise ValueError(f"requirement {self.text[:60]!r}: unknown clause IDs {bad}")

    def words(self, text: str = "", clauses: tuple[str, ...] = ()) -> str:
        """``text`` (default: the requirement's) led by ``clauses`` (default: the requirement's)."""
        lead = "/".join(clauses or self.clauses)
        return f"{lead}: {text or self.text}" if lead else (text or self.text)


@dataclass(frozen=True)
class CaseRecord:
    id: str
    clauses: tuple[str, ...]
    level: Level
    title: str
    expect: str  # the set of acceptable outcomes, in words
    needs: tuple[str, ...] = ()  # "udp", "extension", "any-profile", "always" ...
    requirement: str = ""  # what PROTOCOL.md asks, in words (default: the clauses, level and title)
    #: what the case judges, by name ("" is the default requirement)
    checks: Mapping[str, Requirement] = field(default_factory=lambda: MappingProxyType({}))
    #: the case may run beside other such cases on their own connections (``run``'s lanes,
    #: :mod:`conformance.engine.lanes`): it sets no cycle or extension state and judges no timing
    shares_box: bool = False

    @property
    def family(self) -> str:
        return self.clauses[0][0]

    @property
    def words(self) -> str:
        """The requirement in words: as given, else the clauses, level and title."""
        return self.requirement or f"{', '.join(self.clauses)} ({self.level.value}): {self.title}"

    def check(self, name: str = "") -> Requirement:
        """The named requirement (``""``: the default one, which always exists)."""
        if name in self.checks:
            return self.checks[name]
        if name:
            raise KeyError(f"case {self.id} has no requirement {name!r} (it has: {', '.join(self.checks) or 'none'})")
        return Requirement((), self.words)  # judged: the case's clauses

    def with_param(self, param_id: str) -> CaseRecord:
        return replace(self, id=f"{self.id}[{param_id}]")


def record(id: str, clauses: list[str] | tuple[str, ...], level: Level | str, title: str, expect: str,
           needs: tuple[str, ...] = (), requirement: str = "",
           checks: Mapping[str, Requirement] | None = None, shares_box: bool = False) -> CaseRecord:
    """A checked record: the ID's form and every clause ID against the registry."""
    if not _ID.match(id):
        raise ValueError(f"case id {id!r} must look like 'F1-01' or 'SEQ-S1'")
    bad = [c for c in clauses if not CLAUSE_ID.match(c)]
    if bad or not clauses:
        raise ValueError(f"case {id}: unknown clause IDs {bad or clauses}")
    return CaseRecord(id, tuple(clauses), Level(level), title, expect, tuple(needs), requirement,
                      MappingProxyType(dict(checks or {})), shares_box)


def case(id: str, clauses: list[str] | tuple[str, ...], level: Level | str, title: str, expect: str,
         needs: tuple[str, ...] = (), requirement: str = "",
         checks: Mapping[str, Requirement] | None = None, shares_box: bool = False) -> Callable[[F], F]:
    """Mark a test function as conformance case ``id`` (see :class:`CaseRecord`)."""
    info = record(id, clauses, level, title, expect, needs, requirement, checks, shares_box)

    def deco(fn: F) -> F:
        return pytest.mark.isight_case(info)(fn)

    return deco


def info_of(item: pytest.Item) -> CaseRecord | None:
    marker = item.get_closest_marker(MARKER)
    if marker is None:
        return None
    info: CaseRecord = marker.args[0]
    param = getattr(item, "callspec", None)
    if param is None or not param.id:
        return info
    pid = param.id
    target = str(param.params.get("isight_target", ""))
    if target and pid.endswith(target):  # several boxes: the box is not part of the case's ID
        pid = pid[: -len(target)].removesuffix("-")  # only the dash pytest put before the box's key
    return info.with_param(pid) if pid else info


#: the mark of a case that must run alone (a golden vector that carries a CycleOn, say): no lane shares the box
ALONE_MARK = "isight_alone"
#: actions whose requests change no state a box keeps between requests
STATELESS = frozenset({Action.NONE, Action.POSE, Action.REGISTER_POSE, Action.TOLERANCE})


def stateless_frame(data: bytes) -> bool:
    """One frame (or less: a frame cut short) whose action changes no box state."""
    head = peek_header(data)
    return head is not None and head.action in STATELESS and len(data) <= head.frame_length

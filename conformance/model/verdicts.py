"""Verdicts, levels and the result of one case.

Levels follow RFC 2119 as PROTOCOL.md uses them: a MUST broken is FAIL, a SHOULD
broken is NON-STRICT, a MAY is INFORMATIONAL (recorded, never failing).
"""

from __future__ import annotations

import enum
from dataclasses import asdict, dataclass, field
from typing import Any

from ..protocol.levels import Level
from .signature import Signature


class Verdict(str, enum.Enum):
    PASS = "PASS"
    NON_STRICT = "NON-STRICT"  # a SHOULD is broken
    INFORMATIONAL = "INFORMATIONAL"  # recorded behaviour, never failing (MAY, discovery)
    INCONCLUSIVE = "INCONCLUSIVE"  # could not be judged (box not ready, box unreachable)
    SKIP = "SKIP"  # not applicable (no UDP target, extension not implemented, deselected)
    FAIL = "FAIL"  # a MUST is broken
    ERROR = "ERROR"  # the suite's own fault

    @property
    def failing(self) -> bool:
        return self in (Verdict.FAIL, Verdict.ERROR)


#: The verdict when a box breaks a requirement of each level (RFC 2119's levels: :mod:`conformance.protocol.levels`).
BROKEN = {Level.MUST: Verdict.FAIL, Level.SHOULD: Verdict.NON_STRICT, Level.MAY: Verdict.INFORMATIONAL}


def broken_verdict(level: Level) -> Verdict:
    """The verdict when a box breaks a requirement of ``level``."""
    return BROKEN[level]


#: Order in which reports list verdicts (worst first).
VERDICT_ORDER = (
    Verdict.FAIL, Verdict.ERROR, Verdict.NON_STRICT, Verdict.INCONCLUSIVE,
    Verdict.INFORMATIONAL, Verdict.SKIP, Verdict.PASS,
)


@dataclass(frozen=True)
class WireLine:
    """One line of a case's wire log, as reports show it."""

    t_ms: float  # since the case started
    conn: int
    direction: str  # "→" sent, "←" received, "·" connection event or note
    kind: str
    hex: str
    summary: str  # decoded frame, error clause, or the event


@dataclass
class CaseResult:
    id: str
    title: str
    clauses: tuple[str, ...]
    level: Level
    verdict: Verdict
    duration_s: float = 0.0
    message: str = ""  # one line
    requirement: str = ""  # what PROTOCOL.md asks, in words
    expected: str = ""  # the set of acceptable outcomes
    observed: str = ""  # what the box did
    sent_hex: str = ""  # the bytes that matter (e.g. the malformed frame)
    received_hex: str = ""
    pcap: str | None = None
    wire: list[WireLine] = field(default_factory=list)
    #: timing cases: answer latencies in ms, in request order (for plots)
    latencies_ms: list[float] = field(default_factory=list)
    details: dict[str, Any] = field(default_factory=dict)
    #: the id of the root cause that explains this verdict ("RC1"), when one does
    root_cause: str | None = None
    #: the clause(s) the verdict judged (for a non-PASS verdict; also in ``clauses``): the clause
    #: table marks these, not every clause the case names
    judged: tuple[str, ...] = ()
    #: what the defect looks like, for grouping verdicts under one root cause (None when unknown)
    signature: Signature | None = None

    def to_summary(self) -> dict[str, Any]:
        """The case's entry in summary.json."""
        return {
            "id": self.id,
            "title": self.title,
            "clauses": list(self.clauses),
            "level": self.level.value,
            "verdict": self.verdict.value,
            "duration_s": round(self.duration_s, 4),
            "message": self.message,
            "expected": self.expected,
            "observed": self.observed,
            "sent_hex": self.sent_hex,
            "received_hex": self.received_hex,
            "pcap": self.pcap,
            "judged": list(self.judged),
            "root_cause": self.root_cause,
        }

    def to_dict(self) -> dict[str, Any]:
        out = asdict(self)
        out["level"] = self.level.value
        out["verdict"] = self.verdict.value
        out["clauses"] = list(self.clauses)
        out["judged"] = list(self.judged)
        out["signature"] = None if self.signature is None else self.signature.to_dict()
        return out

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> CaseResult:
        """The inverse of :meth:`to_dict` (a result sent from a pytest-xdist worker)."""
        fields = dict(data)
        fields["level"] = Level(fields["level"])
        fields["verdict"] = Verdict(fields["verdict"])
        fields["clauses"] = tuple(fields["clauses"])
        fields["judged"] = tuple(fields.get("judged", ()))
        fields["wire"] = [WireLine(**w) for w in fields.get("wire", [])]
        sig = fields.get("signature")
        fields["signature"] = Signature.from_dict(sig) if sig else None
        return cls(**fields)


@dataclass
class SuiteInfo:
    version: str
    started: str  # ISO 8601 UTC
    duration_s: float
    target: str  # "10.0.0.5:9000" or "bundled reference box at 127.0.0.1:PORT"
    profile: dict[str, Any]
    udp_target: str | None = None
    extension: str = "auto"  # how E was decided: "detected", "not implemented", "forced on", "off"
    expected_failures: str | None = None  # path of the list, if any
    command: str = ""  # the command line that produced the run
    #: what was tested: "box" (the AI Box, server role: ``run``) or "robot" (client role: ``certify-robot``),
    #: or "observed" (a capture judged by ``analyze``)
    role: str = "box"
    #: False when the run was cut short (Ctrl-C, SIGTERM, SIGHUP): the overall line is then INCOMPLETE
    complete: bool = True
    #: how many cases were selected to run (``len(cases)`` when complete)
    cases_total: int = 0
    #: the ids of selected cases that did not run (an incomplete run)
    not_run: list[str] = field(default_factory=list)
    #: the version of the clause registry the verdicts cite
    registry_version: str = ""
    #: lanes the cases that share the box ran in side by side (``run --lanes``); 1: one case at a time
    lanes: int = 1


@dataclass
class RootCause:
    """One defect that explains several non-PASS verdicts (reported once, first).

    ``cases`` are the ids of the cases it explains; each of those carries
    ``root_cause = id``. Root causes are ordered MUST before SHOULD, then by the cases they explain.
    """

    id: str  # "RC1", "RC2", ... in report order
    clauses: tuple[str, ...]  # the clause(s) the defect breaks (the first is the one judged)
    title: str  # one line: what the box does wrong
    evidence: str  # what shows it: the bytes (hex) and/or a description
    cases: list[str] = field(default_factory=list)
    level: Level = Level.MUST
    #: what kind of defect: "malformed-answers", "one-connection", "connection-leak", "unresponsive", ...
    kind: str = ""
    #: the diagnose phase (conformance/diagnose/): True when an experiment confirmed the mechanism the title
    #: names, False when none did (the title then starts "unconfirmed:"), None when no diagnosis ran
    confirmed: bool | None = None
    #: the hypotheses considered, the experiments that ruled each in or out (with their bytes), the repro file
    diagnosis: dict[str, Any] | None = None

    def to_dict(self) -> dict[str, Any]:
        return {
            "id": self.id,
            "clauses": list(self.clauses),
            "title": self.title,
            "evidence": self.evidence,
            "cases": list(self.cases),
            "level": self.level.value,
            "kind": self.kind,
            "confirmed": self.confirmed,
            "diagnosis": self.diagnosis,
        }

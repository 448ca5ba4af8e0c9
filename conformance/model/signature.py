"""What a defect looks like, as data: a verdict's :class:`Signature` and the session's :class:`Death`.

The judging routine (:mod:`conformance.suite.case_judge`), the run's state (:mod:`conformance.runtime.run_state`),
the certify checks and the FUZZ cases set a signature on the verdicts they raise; :mod:`conformance.engine.rootcause` groups the
verdicts that share one under one root cause, and reads the answer's fields
(:class:`Reply`) to find a field that is wrong the same way in every answer. Nothing is
written as a string and parsed back: ``str(signature)`` is only for people.
"""

from __future__ import annotations

import dataclasses
import enum
from dataclasses import dataclass
from typing import Any


class Sig(str, enum.Enum):
    """The kind of defect a signature names."""

    ANSWER = "answer"  # the answer is malformed (clause, field, value)
    SWAPPED = "swapped"  # the error code's bytes are swapped
    CODE = "code"  # answered ``subject`` with error ``value`` where the case expected another code
    SILENCE = "silence"  # ``subject`` not answered within time_out
    SKIPPED = "skipped"  # a parse error left unanswered: the box went on to the next request
    CLOSED = "closed"  # the box closed the connection instead of answering ``subject``
    UNREACHABLE = "unreachable"  # the case could not reach the box (since case ``subject``)
    DEAD = "dead"  # R2: the box died after case ``subject``'s input
    NOT_ACCEPTING = "not-accepting"  # S5: the box stopped accepting connections
    CASE = "case"  # the case's own finding (never grouped)
    FUZZ = "fuzz"  # fuzzing found it (``clause``; ``field`` "answer" for a malformed answer; ``subject`` the key)
    LEFT_OPEN = "left-open"  # certify-robot: the robot left its ``subject`` connection(s) open
    BACKLOG = "backlog"  # T2: the answer latency grows through a pose stream


@dataclass(frozen=True)
class Reply:
    """The header fields of the box's answer as read (leniently when malformed), and the
    action the case asked for: what a field-wide root cause is found from."""

    asked: int | None  # the action the case expected echoed (None: not known)
    action: int  # the answer's action byte
    error: int  # its error code
    transfer_type: int

    def to_dict(self) -> dict[str, Any]:
        return {"asked": self.asked, "action": self.action, "error": self.error, "transfer_type": self.transfer_type}


@dataclass(frozen=True)
class Signature:
    """One way of failing. Equal signatures are the same defect (``reply`` does not count)."""

    kind: Sig
    subject: str = ""  # an action's name, a case id, a fuzz key, the connections left open
    clause: str = ""  # ANSWER/FUZZ: the clause broken
    field: str = ""  # ANSWER: the field that is wrong ("version", "transfer-type", "shape" ...)
    value: str = ""  # ANSWER: its value; CODE: the error code (4 hex digits)
    reply: Reply | None = dataclasses.field(default=None, compare=False)

    # -- the signatures the suite writes ----------------------------------------------------------
    @classmethod
    def unreachable(cls, since: str) -> Signature:
        """Refused at once: the box has been unreachable since case ``since`` ("connect", "session start")."""
        return cls(Sig.UNREACHABLE, since)

    @classmethod
    def own(cls, case_id: str) -> Signature:
        """A case's own finding: grouped with nothing."""
        return cls(Sig.CASE, case_id)

    @classmethod
    def fuzz(cls, clause: str, *, malformed_answer: bool = False, key: str = "") -> Signature:
        """A fuzz finding: of ``clause``; a malformed answer joins the cases that found the same malformation."""
        return cls(Sig.FUZZ, key, clause, "answer" if malformed_answer else "")

    @property
    def groups(self) -> bool:
        """Whether verdicts with this signature may form a root cause of their own."""
        return self.kind not in (Sig.UNREACHABLE, Sig.CASE)

    def __str__(self) -> str:
        if self.kind is Sig.ANSWER:
            return f"answer:{self.clause}:{self.field}" + (f"={self.value}" if self.value else "")
        if self.kind is Sig.CODE:
            return f"code:{self.subject}:{self.value}"
        if self.kind is Sig.FUZZ:
            return f"fuzz:{self.subject or (f'{self.field}/' if self.field else '') + self.clause}"
        return f"{self.kind.value}:{self.subject}" if self.subject else self.kind.value

    # -- across pytest-xdist ----------------------------------------------------------------------
    def to_dict(self) -> dict[str, Any]:
        return {"kind": self.kind.value, "subject": self.subject, "clause": self.clause, "field": self.field,
                "value": self.value, "reply": None if self.reply is None else self.reply.to_dict()}

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> Signature:
        reply = data.get("reply")
        return cls(Sig(data["kind"]), data.get("subject", ""), data.get("clause", ""), data.get("field", ""),
                   data.get("value", ""), None if reply is None else Reply(**reply))


class DeathKind(str, enum.Enum):
    """How the box stopped answering; the words are the kinds of the root causes deaths become."""

    UNRESPONSIVE = "unresponsive"  # never answered a NONE request (the session's baseline)
    DEAD_AFTER_INPUT = "dead-after-input"  # R2: no fresh connection answered after a case's input
    CONNECTION_LEAK = "connection-leak"  # S5: alive on an open connection, but accepts no new one


@dataclass(frozen=True)
class Death:
    """The box stopped answering fresh connections after a case (a fact for root causes),
    from the session that saw it through pytest-xdist to the root causes."""

    case_id: str  # the case after which it happened ("session start" for the baseline)
    kind: DeathKind
    detail: str
    opened: int  # TCP connections the suite had opened in the session
    closed: int  # ... and closed

    def to_dict(self) -> dict[str, Any]:
        return {"case_id": self.case_id, "kind": self.kind.value, "detail": self.detail, "opened": self.opened,
                "closed": self.closed}

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> Death:
        return cls(data["case_id"], DeathKind(data["kind"]), data["detail"], int(data["opened"]), int(data["closed"]))

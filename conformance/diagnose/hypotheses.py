"""Typed values of the diagnose phase, and the pure judgements on them (no sockets here).

An :class:`Exchange` is what one fresh connection saw: the frames sent in order and, after
each, a :class:`Reading` (the answers heard, a close, silence). An :class:`Experiment`
groups the exchanges that answer one question. A :class:`Hypothesis` is one story that
could explain a root cause; its :class:`Status` is set by the experiment named in it. A
:class:`Mechanism` is what the experiments confirmed about the box (with its threshold,
the actions it touches and the frames of its minimal repro); a root cause's
:class:`Diagnosis` lists every hypothesis considered and the confirmed one, if any.
"""

from __future__ import annotations

import enum
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

from ..protocol import Action


class Status(str, enum.Enum):
    CONFIRMED = "confirmed"
    RULED_OUT = "ruled out"
    CONSISTENT = "not ruled out"  # the experiments fit it, but fit another story too
    UNTESTED = "untested"  # no experiment was run (out of time, or the box stopped answering)


@dataclass(frozen=True)
class Heard:
    """One answer (or malformed bytes) from the box: its header's action and error when readable."""

    action: int | None
    error: int | None
    raw: bytes
    malformed: str = ""  # what is wrong with it ("" for a well-formed answer)

    def to_dict(self) -> dict[str, Any]:
        return {"action": self.action, "error": self.error, "hex": self.raw.hex(), "malformed": self.malformed}


@dataclass(frozen=True)
class Reading:
    """What followed one frame: the answers heard within the wait, and whether the box closed or stayed silent."""

    answers: tuple[Heard, ...] = ()
    closed: bool = False

    @property
    def silent(self) -> bool:
        return not self.answers and not self.closed

    def to_dict(self) -> dict[str, Any]:
        return {"answers": [a.to_dict() for a in self.answers], "closed": self.closed}


@dataclass(frozen=True)
class Exchange:
    """Frames sent in order on one fresh connection, and what followed each."""

    frames: tuple[bytes, ...]
    readings: tuple[Reading, ...]
    reached: bool = True  # False: the connection could not be made
    together: bool = False  # the frames went in one write; ``readings`` is one reading of every answer

    def reading(self, i: int) -> Reading:
        return self.readings[i] if i < len(self.readings) else Reading(closed=True)

    def to_dict(self) -> dict[str, Any]:
        return {"sent": [f.hex() for f in self.frames], "readings": [r.to_dict() for r in self.readings],
                "reached": self.reached, "one_write": self.together}


@dataclass
class Experiment:
    """One question put to the box, the exchanges that answered it and what they showed."""

    name: str
    question: str
    exchanges: list[Exchange] = field(default_factory=list)
    finding: str = ""

    def to_dict(self) -> dict[str, Any]:
        return {"name": self.name, "question": self.question, "finding": self.finding,
                "exchanges": [e.to_dict() for e in self.exchanges[:12]], "exchange_count": len(self.exchanges)}


@dataclass(frozen=True)
class Hypothesis:
    """One story for a root cause, and what the experiment named in it said about it."""

    key: str  # the mechanism's kind: "count-limit", "byte-limit", "index", "extra-answer", ...
    statement: str
    status: Status = Status.UNTESTED
    experiment: str = ""  # the name of the experiment that ruled it in or out
    why: str = ""

    def to_dict(self) -> dict[str, Any]:
        return {"key": self.key, "statement": self.statement, "status": self.status.value,
                "experiment": self.experiment, "why": self.why}


@dataclass(frozen=True)
class Expect:
    """The legal answers to one frame of a repro: ``valid`` (exactly one answer, the action echoed, an
    error code in ``codes``) or ``invalid`` (never a 0000 answer with its action; silence and a close are legal)."""

    kind: str  # "valid" | "invalid"
    action: int
    codes: tuple[int, ...] = (0,)

    def to_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {"kind": self.kind, "action": self.action}
        if self.kind == "valid":
            out["errorCodes"] = list(self.codes)
        return out

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> Expect:
        return cls(str(data["kind"]), int(data["action"]), tuple(int(c) for c in data.get("errorCodes", (0,))))

    def take(self, answers: list[Heard]) -> Reading:
        """From the answers to frames sent in one write (in order), the ones that belong to this frame: a valid
        request's first answer; a parse error's answer when it carries its action (it may have none)."""
        if not answers:
            return Reading()
        if self.kind == "valid" or answers[0].action == self.action:
            return Reading((answers.pop(0),))
        return Reading()

    def broken_by(self, reading: Reading) -> str:
        """What in ``reading`` is outside the legal set ("" when it is legal)."""
        if self.kind == "invalid":
            zero = [a for a in reading.answers if a.action == self.action and a.error == 0]
            return f"a request that is a parse error was answered 0000 ({zero[0].raw.hex(' ')})" if zero else ""
        if reading.closed and not reading.answers:
            return "the box closed the connection instead of answering"
        if not reading.answers:
            return "no answer within time_out"
        if len(reading.answers) > 1:
            return f"{len(reading.answers)} answers to one request"
        a = reading.answers[0]
        if a.malformed:
            return f"a malformed answer: {a.malformed}"
        if a.action != self.action:
            return f"answered with action {_hex2(a.action)} (asked {self.action:02X})"
        if a.error not in self.codes:
            return f"answered error {_hex4(a.error)} (legal: {', '.join(f'{c:04X}' for c in self.codes)})"
        return ""


def _hex2(v: int | None) -> str:
    return "??" if v is None else f"{v:02X}"


def _hex4(v: int | None) -> str:
    return "????" if v is None else f"{v:04X}"


#: the legal error codes of a valid request answered alone (S2, S3: a cycle request may be refused by state)
LEGAL_CODES: dict[int, tuple[int, ...]] = {
    Action.NONE: (0,), Action.CYCLE_ON: (0, 1), Action.CYCLE_OFF: (0, 2), Action.POSE: (0,),
    Action.REGISTER_POSE: (0,), Action.TOLERANCE: (0,),
}


@dataclass(frozen=True)
class Mechanism:
    """A defect the experiments confirmed: its kind, the actions it touches, its threshold, and its repro."""

    kind: str  # see :data:`KINDS`
    actions: frozenset[int]
    experiment: str
    title: str
    clauses: tuple[str, ...]
    repro: tuple[tuple[bytes, Expect], ...]  # frames on one fresh connection, with their legal answers
    detail: dict[str, Any] = field(default_factory=dict)  # threshold, wrong action, error code ...

    def to_dict(self) -> dict[str, Any]:
        return {"kind": self.kind, "actions": sorted(self.actions), "experiment": self.experiment,
                "clauses": list(self.clauses), **{k: v for k, v in self.detail.items() if k != "hex"}}


#: mechanism kinds, in the order one explains a root cause before the next
KINDS: tuple[str, ...] = (
    "count-limit", "byte-limit", "index",
    # answers built wrongly and fields accepted (:mod:`.answer_family`, :mod:`.block_length`): after the size kinds
    "block-length", "block-count", "error-byte-order", "answer-shape",
    "extra-answer", "echo-one", "echo-all", "cycle-dependent", "state-leak", "connection-count",
    "latency-per-block", "latency-per-request", "stall", "late-answer",
    "peer-close", "open-limit", "idle-close", "age-close", "missing-answer", "refuses-valid",
    "order-dependent", "reproduces")


# -- answers to one valid request alone (pure) ---------------------------------------------------------------
@dataclass(frozen=True)
class Alone:
    """How the box answered one valid request alone on a fresh connection (a NONE right after it)."""

    action: int
    kind: str  # "ok" | "extra" | "echo" | "missing" | "refused" | "closed" | "malformed" | "silent"
    count: int = 1  # answers to the request
    answered_action: int | None = None
    error: int | None = None


def classify_alone(action: int, exchange: Exchange) -> Alone:
    """The request (frame 0) then a NONE (frame 1) on one connection: what the box did with the request.

    Answers come in order (A1): every answer heard before the NONE was sent belongs to the request, and an
    answer with the request's action read after the NONE is a late extra."""
    first, after = exchange.reading(0), exchange.reading(1)
    heard = list(first.answers)
    if not heard and first.closed:
        return Alone(action, "closed", 0)
    total = len(heard) + len(after.answers)
    if not heard:
        if after.answers:
            if total >= 2:  # the request's answer came after the wait (late): not missing
                return Alone(action, "ok" if after.answers[0].action == action else "echo", 1,
                             after.answers[0].action, after.answers[0].error)
            return Alone(action, "missing", 0)
        return Alone(action, "silent", 0)
    # a late extra answer to the request is read after the NONE was sent, before the NONE's own (last) answer, with
    # the request's action (a NONE answered twice is the NONE's own defect; a box answering everything with the
    # request's action answers the NONE with it too)
    extra = len(heard) + sum(1 for b in after.answers[:-1] if b.action == action != 0)
    a = heard[0]
    if a.malformed:
        return Alone(action, "malformed", extra, a.action, a.error)
    if extra >= 2:
        return Alone(action, "extra", extra, a.action, a.error)
    if a.action != action:
        return Alone(action, "echo", 1, a.action, a.error)
    if a.error not in LEGAL_CODES.get(action, (0,)):
        return Alone(action, "refused", 1, a.action, a.error)
    return Alone(action, "ok", 1, a.action, a.error)


def answered_well(action: int, answers: Sequence[Heard]) -> bool:
    """One well-formed answer with the request's action and 0000: what :func:`classify_alone` calls ``ok`` for a
    pose, read where no NONE follows (the pose inside a cycle). A malformed answer is never well answered, so a
    box whose every answer is malformed (F3) shows no difference between the cycle's arms."""
    return len(answers) == 1 and not answers[0].malformed and answers[0].action == action and answers[0].error == 0


def echo_story(alone: Sequence[Alone]) -> tuple[str, int | None, frozenset[int]]:
    """Echo wrong for every action (``echo-all``, the constant action) vs for one (``echo-one``), from the
    requests answered once; ``("", None, {})`` when every action is echoed."""
    wrong = [a for a in alone if a.kind == "echo"]
    right = [a for a in alone if a.kind == "ok"]
    if not wrong:
        return "", None, frozenset()
    values = {a.answered_action for a in wrong}
    if len(wrong) >= 2 and len(values) == 1 and len(right) <= 1:
        return "echo-all", values.pop(), frozenset(a.action for a in wrong)
    return "echo-one", None, frozenset(a.action for a in wrong)


# -- size: count vs bytes vs index (pure) -----------------------------------------------------------------------
@dataclass(frozen=True)
class SizeFacts:
    """What the size experiments measured: per block size, the smallest refused count (None: 255 accepted),
    and whether a wrong index at the position where acceptance changes was accepted."""

    thresholds: dict[int, int | None]  # block length (25 pose, 5 tolerance) -> smallest refused valid count
    wrong_index_accepted: tuple[int, int] | None = None  # (1-based block, index value) accepted there
    wrong_index_tried: int = 0


def frame_len(count: int, block_len: int) -> int:
    return 12 + count * block_len + 2


def size_story(facts: SizeFacts) -> tuple[str, dict[str, Any], list[tuple[str, Status, str]]]:
    """The size family's verdict: the confirmed kind ("" for none), its numbers, and each story's status."""
    th = {length: t for length, t in facts.thresholds.items()}
    refused = {length: t for length, t in th.items() if t is not None}
    if not refused:
        why = "every count up to 255 accepted at every block size"
        return "", {}, [("count-limit", Status.RULED_OUT, why), ("byte-limit", Status.RULED_OUT, why),
                        ("index", Status.RULED_OUT, why)]
    if facts.wrong_index_accepted is not None:
        block, value = facts.wrong_index_accepted
        k = min(refused.values())
        why = f"a wrong index ({value}) at block {block} was answered 0000"
        return "index", {"threshold": k, "block": block, "value": value}, [
            ("index", Status.CONFIRMED, why), ("count-limit", Status.RULED_OUT, why), ("byte-limit", Status.RULED_OUT, why)]
    counts = set(refused.values())
    same_count = len(counts) == 1 and len(refused) == len(th)
    lo, hi = _byte_window(th)
    bytes_fit = lo is not None and hi is not None and lo < hi
    index_why = (f"no wrong index tried at the changing position was accepted ({facts.wrong_index_tried} tried)"
                 if facts.wrong_index_tried else "not tried")
    index_status = Status.RULED_OUT if facts.wrong_index_tried else Status.UNTESTED
    if same_count and len(th) >= 2:
        n = counts.pop()
        why = f"refused from {n} blocks at every block size ({', '.join(f'{frame_len(n, b)} bytes' for b in sorted(th))})"
        return "count-limit", {"threshold": n}, [
            ("count-limit", Status.CONFIRMED, why), ("byte-limit", Status.RULED_OUT, why), ("index", index_status, index_why)]
    if bytes_fit:
        assert lo is not None and hi is not None
        why = "; ".join(f"{b}-byte blocks refused from {t} ({frame_len(t, b)} bytes)" if t is not None else
                        f"{b}-byte blocks accepted up to 255 ({frame_len(255, b)} bytes)" for b, t in sorted(th.items()))
        every = len(refused) == len(th) >= 2  # refused at every block size, at different counts: one byte size
        kind = "byte-limit" if every else ""
        return kind, {"max_bytes": lo, "refused_bytes": hi}, [
            ("byte-limit", Status.CONFIRMED if every else Status.CONSISTENT, why),
            ("count-limit", Status.RULED_OUT if every else Status.CONSISTENT,
             "the refused count differs with the block size" if every else
             "no legal frame of another block size is as long: a count limit of this block type fits too"),
            ("index", index_status, index_why)]
    # refused counts differ and no one byte size fits: a count limit of one action's block type
    length, n = min(refused.items(), key=lambda kv: kv[1])
    why = f"{length}-byte blocks refused from {n}; other block sizes accepted at sizes that rule out a byte limit"
    return "count-limit", {"threshold": n, "block_len": length, "per_type": True}, [
        ("count-limit", Status.CONFIRMED, why), ("byte-limit", Status.RULED_OUT, why), ("index", index_status, index_why)]


def _byte_window(th: dict[int, int | None]) -> tuple[int | None, int | None]:
    """The frame sizes a byte limit must lie in: (largest accepted frame, smallest refused frame)."""
    accepted = [frame_len((t - 1) if t is not None else 255, b) for b, t in th.items()]
    refused = [frame_len(t, b) for b, t in th.items() if t is not None]
    if not refused:
        return None, None
    return max(accepted), min(refused)


def index_candidates(position: int, first_index: int) -> list[int]:
    """Wrong index values a box that judges indexes wrongly might expect at 0-based ``position``: a counter
    of 4, 5, 6 or 7 bits, one that restarts at 100, the first index again, one behind, one ahead."""
    right = (first_index + position) & 0xFF
    raw = [(first_index + position) & m for m in (0x0F, 0x1F, 0x3F, 0x7F)]
    raw += [(first_index + position) % 100, first_index, (right - 1) & 0xFF, (right + 1) & 0xFF]
    return [v for v in dict.fromkeys(raw) if v != right]

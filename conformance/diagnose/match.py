"""Which confirmed mechanism explains a root cause, and the hypotheses each root cause lists (pure).

A root cause is read as :class:`CauseFacts`: its kind (the catalogue's story), the actions its
cases asked for and the actions the box answered with. A mechanism explains it when they share
an action (an extra answer also explains answers *with* its action given to other requests: the
shift). When several do, the first in :data:`~.hypotheses.KINDS` order wins. Every family that
ran lists its stories as this root cause's hypotheses, each confirmed, ruled out or untested,
with the experiment that said so.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

from ..model.signature import Sig
from ..model.verdicts import CaseResult, RootCause
from ..protocol import parse_header
from ..protocol.constants import HEADER_LEN, START_WORD
from ..protocol.framings import embedded_actions
from .hypotheses import KINDS, Hypothesis, Mechanism, Status

#: the catalogue's stories (root-cause kinds) and the mechanisms that are the same story told exactly
SAME_STORY = {"block-position": {"index"}, "action-not-echoed": {"echo-all"}, "constant-error": {"refuses-valid"},
              "unanswered": {"missing-answer"}}
#: root causes found by the session's own live checks on fresh connections (already experiments)
SESSION_KINDS = ("unresponsive", "one-connection", "dead-after-input", "connection-leak", "box-stall")
_NAMES = {"count-limit": "a limit on the block count", "byte-limit": "a limit on the frame's size in bytes",
          "index": "block indexes judged wrongly", "extra-answer": "an extra answer that shifts later answers",
          "echo-one": "the action echoed wrongly for one action", "echo-all": "the action echoed wrongly for every action",
          "missing-answer": "an answer missing (later answers shifted back)", "refuses-valid": "a valid request refused",
          "state-leak": "state left by an error answer spoils the next answer",
          "cycle-dependent": "depends on the cycle state", "connection-count": "depends on how many requests the "
          "connection carried", "idle-close": "closes a connection left idle for some time",
          "peer-close": "another connection (opened, or a cycle request on it) closes this one",
          "open-limit": "no more than some number of connections served at once",
          "age-close": "closes every connection some time after it opened", "closes-at-request": "the request "
          "itself closes the connection", "order-dependent": "shows only after other frames on the same connection", "reproduces": "a defect of the request alone (reproduces on a fresh connection)"}

_NAMES.update({"block-length": "a wrong block length accepted", "block-count": "block count 0 accepted", "error-byte-order": "error codes written little-endian",
               "answer-shape": "an answer's fields built wrongly"})


def statement(kind: str) -> str:
    return _NAMES.get(kind, kind)


@dataclass(frozen=True)
class CauseFacts:
    kind: str
    asked: frozenset[int]  # actions the cases asked for
    answered: frozenset[int]  # actions the box answered them with
    most_blocks: int = 0  # the largest block count among the requests the cases quote
    longest: int = 0  # the longest frame (bytes) among them
    closed: bool = False  # a case saw the box close (or reset) the connection where it should have answered


def facts_of(cause: RootCause, cases: Sequence[CaseResult]) -> CauseFacts:
    members = [c for c in cases if c.id in set(cause.cases)]
    asked: set[int] = set()
    answered: set[int] = set()
    for case in members:
        sig = case.signature
        if sig is not None and sig.reply is not None:
            if sig.reply.asked is not None:
                asked.add(sig.reply.asked)
            answered.add(sig.reply.action)
        asked.update(_sent_actions(case.sent_hex, anywhere=cause.kind == "fuzz"))
        if cause.kind == "fuzz":  # a fuzz finding names no answer: the actions the box answered with, as quoted
            answered.update(_sent_actions(case.received_hex, anywhere=True))
    sizes = [size for case in members for size in _sizes(case.sent_hex)]
    return CauseFacts(cause.kind, frozenset(asked), frozenset(answered), max((n for n, _ in sizes), default=0),
                      max((length for _, length in sizes), default=0), any(map(_closed, members)))


#: what a case observed when the box closed (or reset) the connection (:mod:`conformance.harness.outcomes`)
_CLOSE_WORDS = ("closed the connection", "reset the connection")


def _closed(case: CaseResult) -> bool:
    sig = case.signature
    return (sig is not None and sig.kind is Sig.CLOSED) or any(w in case.observed for w in _CLOSE_WORDS)


def _sizes(sent_hex: str) -> list[tuple[int, int]]:
    """(block count, frame length) of the first request header the quoted bytes start with (its length as the
    header announces it: a quote may be cut short)."""
    try:
        raw = bytes.fromhex(sent_hex.partition("…")[0])
    except ValueError:
        return []
    if len(raw) < HEADER_LEN:
        return []
    header = parse_header(raw[:HEADER_LEN])
    if header.start_word != START_WORD:
        return []
    return [(header.block_count, HEADER_LEN + header.block_count * header.block_length + 2)]


def _sent_actions(sent_hex: str, anywhere: bool = False) -> set[int]:
    """The actions of the frames the quoted request bytes hold, as far as quoted (headers with the start word);
    ``anywhere``: of every header some legal framing may read in them (a fuzz finding's bytes start anyhow)."""
    try:
        raw = bytes.fromhex(sent_hex.partition("…")[0])
    except ValueError:
        return set()
    if anywhere:
        return set(embedded_actions(raw))
    out: set[int] = set()
    at = 0
    while len(raw) - at >= HEADER_LEN:
        header = parse_header(raw[at:at + HEADER_LEN])
        if header.start_word != START_WORD:
            break
        out.add(header.action)
        at += HEADER_LEN + header.block_count * header.block_length + 2
    return out


def explains(m: Mechanism, f: CauseFacts) -> bool:
    if "explains" in m.detail:  # a mechanism that explains only the catalogue's stories it names
        return f.kind in m.detail["explains"] and bool(m.actions & f.asked)
    if m.kind in ("count-limit", "byte-limit", "index"):  # the story the catalogue read, or its cases' sizes
        if f.kind == "block-position":
            return True
        if not m.actions & f.asked:
            return False
        if m.kind == "byte-limit":
            return f.longest > int(m.detail.get("max_bytes", 0))
        return f.most_blocks >= int(m.detail.get("threshold", m.detail.get("block", 256)))
    if m.kind in ("peer-close", "open-limit", "idle-close", "age-close"):  # a close in place of an answer, whatever was asked (conn_state)
        return f.kind == "closes" or f.closed
    if m.kind == "extra-answer":
        return bool(m.actions & (f.asked | f.answered))
    if m.kind == "echo-all":
        return f.kind in ("action-not-echoed", "wrong-code", "constant-error") or bool(m.actions & f.asked)
    return bool(m.actions & f.asked)


def pick(mechanisms: Sequence[Mechanism], f: CauseFacts) -> Mechanism | None:
    fitting = [m for m in mechanisms if explains(m, f)]
    return min(fitting, key=lambda m: KINDS.index(m.kind)) if fitting else None


def hypotheses(f: CauseFacts, title: str, chosen: Mechanism | None, stories: Mapping[str, tuple[Status, str, str]],
               ) -> list[Hypothesis]:
    """This root cause's hypotheses: the catalogue's own story first, then every family's stories."""
    out: list[Hypothesis] = []
    if chosen is None:
        own = Hypothesis("catalogue", f"as read from the verdicts: {title}", Status.CONSISTENT, "",
                         "no experiment confirmed a mechanism for it")
    elif chosen.kind in SAME_STORY.get(f.kind, set()) or chosen.kind == "reproduces":
        own = Hypothesis("catalogue", f"as read from the verdicts: {title}", Status.CONFIRMED, chosen.experiment,
                         "the experiment shows the same mechanism")
    else:
        own = Hypothesis("catalogue", f"as read from the verdicts: {title}", Status.RULED_OUT, chosen.experiment,
                         f"the experiment shows another mechanism: {statement(chosen.kind)}")
    out.append(own)
    for kind, (status, why, experiment) in stories.items():
        if chosen is not None and kind == chosen.kind:
            out.append(Hypothesis(kind, statement(kind), Status.CONFIRMED, experiment, why or chosen.title))
            continue
        if status is Status.CONFIRMED:  # confirmed for other actions: it does not explain this root cause
            status, why = Status.RULED_OUT, "confirmed for other requests, not for this root cause's"
        elif chosen is not None and status is Status.CONSISTENT:
            status, why = Status.RULED_OUT, f"the experiments confirm another mechanism: {statement(chosen.kind)}"
        out.append(Hypothesis(kind, statement(kind), status, experiment, why))
    return out

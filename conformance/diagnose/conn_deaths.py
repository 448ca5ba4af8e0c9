"""A box that stopped accepting new connections (S5) while still serving one it accepted earlier: the input of
the case before it, or a count of connections?

Two stories fit one such death: an input that broke the box's listener (R2), and a fixed table of connection
state that fills as connections close and is never freed (S5). Without a restart the box cannot be tried again,
so the judgement reads the session's own evidence (pure, no sockets):

* for the input story: the input announces more block bytes than the largest legal frame (what a listener's
  error path is likely to choke on) — :func:`.death_inputs.oversize`;
* against it: earlier cases of the same test (the same kind of input, e.g. ``A5-01[transfer-02]`` before
  ``A5-01[transfer-ff]``) passed and the box went on accepting; or the case sent only valid requests.

With evidence against the input story and none for it, the title states the count (connections opened and
closed before the first refused one); with neither, both stories, ``unconfirmed:``.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

from ..model.signature import Death, DeathKind
from ..model.verdicts import CaseResult, RootCause, Verdict
from ..protocol import Profile, ProtocolError, codec_for
from . import conn_titles, death_inputs, titles
from .hypotheses import Hypothesis, Status


@dataclass(frozen=True)
class Evidence:
    """What the session's cases say about the input story of a death after case ``case``."""

    case: str
    oversize: bool  # the input announces more than the largest legal frame
    same_kind_passed: int  # earlier cases of the same test that passed, the box accepting after each
    only_valid: bool  # the case's input parses as valid requests only


def test_of(case_id: str) -> str:
    """A case's test: its id without the parameter ("A5-01[transfer-ff]" -> "A5-01")."""
    return case_id.partition("[")[0]


def evidence(killer: CaseResult, cases: Sequence[CaseResult]) -> Evidence:
    """The evidence about ``killer``'s input from the cases run before it (``cases`` in run order)."""
    sent = death_inputs.inputs(killer)
    big = any(death_inputs.oversize(b) is not None for b in sent)
    before = []
    for case in cases:
        if case.id == killer.id:
            break
        before.append(case)
    test = test_of(killer.id)
    same = sum(1 for c in before if c.id != killer.id and test_of(c.id) == test and "[" in c.id
               and c.verdict is Verdict.PASS)
    return Evidence(killer.id, big, same, bool(sent) and all(_valid(b) for b in sent))


def _valid(data: bytes) -> bool:
    codec = codec_for(Profile())
    at = 0
    try:
        while at < len(data):
            n = codec.frame_length(data[at:])
            codec.parse(data[at:at + n])
            at += n
    except (ProtocolError, ValueError, IndexError):
        return False
    return at == len(data) > 0


def judge(ev: Evidence) -> tuple[str, str]:
    """("count" | "input" | "both", why): which story the evidence supports."""
    if ev.oversize:
        return "input", "the input announces more block bytes than the largest legal frame"
    if ev.same_kind_passed:
        return "count", conn_titles.same_kind_passed(ev.same_kind_passed, test_of(ev.case))
    if ev.only_valid:
        return "count", conn_titles.nothing_unusual()
    return "both", "no earlier case sent an input of its kind, and one death cannot be tried again without a restart"


def name(causes: Sequence[RootCause], cases: Sequence[CaseResult], deaths: Sequence[Death]) -> None:
    """Retitle each confirmed connection leak with the story its evidence supports (in place; after
    :func:`.death_inputs.name`, whose input title stands when the input story is the one supported)."""
    by_id = {c.id: c for c in cases}
    for cause in causes:
        if cause.kind != DeathKind.CONNECTION_LEAK.value or not cause.confirmed:
            continue
        killer = next((by_id[i] for i in cause.cases if i in by_id), None)
        death = next((d for d in deaths if killer is not None and d.case_id == killer.id), None)
        if killer is None or death is None:
            continue
        story, why = judge(evidence(killer, cases))
        if story == "input":
            continue
        if story == "count":
            cause.title = conn_titles.leak_count(death.opened, death.closed, killer.id, why)
        else:
            cause.title = titles.unconfirmed(conn_titles.leak_or_input(death.opened, death.closed, killer.id))
            cause.confirmed = False
        _note(cause, story, why)


def _note(cause: RootCause, story: str, why: str) -> None:
    """The two stories and what the evidence said of each, in the root cause's diagnosis."""
    strong = why == conn_titles.nothing_unusual()  # the case sent nothing an input story could blame
    count = Status.CONFIRMED if story == "count" and strong else Status.CONSISTENT
    inp = Status.RULED_OUT if story == "count" and strong else Status.CONSISTENT
    for_count = why if strong or story != "count" else f"supported, not proven (no restart to try again): {why}"
    for_input = why if strong or story != "count" else f"weakened, not ruled out: {why}"
    hyps = [Hypothesis("connection-count-leak", "the state of closed connections is never freed: a fixed number of "
                       "connections, then no more", count, "session", for_count),
            Hypothesis("input-kills-listener", "the case's input stopped the box accepting connections", inp,
                       "session", for_input)]
    diagnosis = dict(cause.diagnosis or {})
    diagnosis["hypotheses"] = [*diagnosis.get("hypotheses", []), *(h.to_dict() for h in hyps)]
    diagnosis["confirmed"] = cause.confirmed
    cause.diagnosis = diagnosis

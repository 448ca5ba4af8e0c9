"""A death the session saw, put to the test again: is the box still silent, and does the same input kill it twice?

The session concludes "dead after case X" (R2), "connections never freed" (S5) or "never answers
NONE" (A4/T1) when a NONE request on a fresh connection goes unanswered within time_out. On a
loaded machine, or with a short time_out, a slow answer looks the same. So before the other
experiments the phase asks again, on a fresh connection:

* still silent: the death is confirmed (and nothing else is probed: the box answers nothing);
* answering again, after a death after case X: case X's bytes are sent again (as the case sent them,
  in one write) and a fresh connection checked once more: silent again, the death is confirmed (the
  input kills the box); answered, it is not (unconfirmed), and the other root causes are diagnosed.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

from ..model.verdicts import CaseResult, RootCause
from .experiments import Prober
from .hypotheses import Exchange, Experiment, Hypothesis, Status

DEATH_KINDS = ("unresponsive", "dead-after-input", "connection-leak")


@dataclass
class Verdict:
    confirmed: bool
    experiment: Experiment
    why: str


def alive(p: Prober, exp: Experiment) -> bool | None:
    """A NONE on a fresh connection answered (None: out of time)."""
    ex = p.exchange([p.valid_request(0)], settle=False)
    if ex is None:
        return None
    exp.exchanges.append(ex)
    return ex.reached and bool(ex.reading(0).answers)


def check(p: Prober, cause: RootCause, cases: Sequence[CaseResult]) -> Verdict:
    exp = Experiment("still-dead", "a NONE on a fresh connection now; after a death after a case's input, that "
                                   "input again, then a NONE on a fresh connection")
    now = alive(p, exp)
    if now is None:
        return Verdict(False, exp, "out of time")
    if not now:
        exp.finding = "a fresh connection is still not answered"
        return Verdict(True, exp, exp.finding)
    if cause.kind != "dead-after-input":
        exp.finding = "the box answers a fresh connection again"
        return Verdict(False, exp, exp.finding)
    by_id = {c.id: c for c in cases}
    killer = next((by_id[i] for i in cause.cases[:1] if i in by_id), None)
    if killer is None or not killer.sent_hex or "…" in killer.sent_hex:
        exp.finding = "the box answers a fresh connection again; the input that killed it is not quoted whole"
        return Verdict(False, exp, exp.finding)
    data = bytes.fromhex(killer.sent_hex)
    sent: Exchange | None = p.exchange([data], quiet=[True], settle=False, together=True)
    if sent is not None:
        exp.exchanges.append(sent)
    again = alive(p, exp)
    if again is False:
        exp.finding = f"answering again, then silent once more after case {killer.id}'s input: the input kills it"
        return Verdict(True, exp, exp.finding)
    exp.finding = f"the box answers a fresh connection again, also after case {killer.id}'s input sent once more"
    return Verdict(False, exp, exp.finding)


def diagnosis(cause: RootCause, verdict: Verdict) -> dict[str, object]:
    status = Status.CONFIRMED if verdict.confirmed else Status.RULED_OUT
    h = Hypothesis(cause.kind, cause.title, status, verdict.experiment.name, verdict.why)
    slow = Hypothesis("slow", "a slow answer (the box answered later than time_out, or the machine was loaded)",
                      Status.RULED_OUT if verdict.confirmed else Status.CONSISTENT, verdict.experiment.name, verdict.why)
    return {"confirmed": verdict.confirmed, "mechanism": cause.kind if verdict.confirmed else None,
            "catalogue_title": cause.title, "hypotheses": [h.to_dict(), slow.to_dict()],
            "experiments": [verdict.experiment.to_dict()]}

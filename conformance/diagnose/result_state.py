"""The result request's state (E3): a ResultCode E3 does not allow before the first cycle, a legal one after it.

The engine claims the pair (:mod:`conformance.engine.history_causes`): the run's first result request,
at session start, got a ResultCode E3 does not allow (0, the robot's empty initial value, say), while
the same request after the suite's cycles got a legal one. Two stories remain: the box answers every
*first* result request of a connection that way (then a fresh connection now shows it again), or its
result is wrong only until a cycle has ended (then a fresh connection now gets a legal code, as after
the cycles). One result request on a fresh connection tells them apart; the box cannot be taken back
to before its first cycle without a restart, which ``run`` does not do, and the title says so.
"""

from __future__ import annotations

from collections.abc import Sequence

from ..engine.history_causes import RESULT_BEFORE_CYCLE
from ..i18n import gettext
from ..model.verdicts import CaseResult, RootCause
from ..protocol import Action
from ..protocol.answers import SENDABLE_RESULTS, block_value
from . import titles
from .experiments import Prober
from .hypotheses import Experiment, Hypothesis, Status

#: the root-cause kinds this module diagnoses
KINDS = (RESULT_BEFORE_CYCLE,)


def title_for(first: int | None, now: int) -> str:
    seen = gettext("ResultCode {code}").format(code=first) if first is not None else gettext("a malformed answer")
    return gettext("Answers the result request (27) with {seen} before its first cycle (at session start) and with a "
                   "legal ResultCode once a cycle has run (now {now}, on a fresh connection): its result is not "
                   "initialised until the first cycle ends, and E3 never allows 0 (the robot's empty initial "
                   "value) — give the result a legal value (e.g. 202, busy) before the first cycle").format(
        seen=seen, now=now)


def run(p: Prober, cause: RootCause, cases: Sequence[CaseResult]) -> None:
    """A result request on a fresh connection now: a legal ResultCode confirms the first-cycle story."""
    exp = Experiment("result-now", "a result request (27) on a fresh connection, after the suite's cycles: is it "
                                   "answered with a legal ResultCode now?")
    ex = p.exchange([p.valid_request(int(Action.VISION_RESULT))], settle=False)
    answers = ex.reading(0).answers if ex is not None and ex.reached else ()
    if ex is not None:
        exp.exchanges.append(ex)
    now = block_value(answers[0].raw, p.profile.byte_order) if answers else None
    first = next((c.details.get("result_code") for c in cases if c.id in cause.cases), None)
    legal = now is not None and now in SENDABLE_RESULTS
    exp.finding = f"ResultCode {now}" if now is not None else "no ResultCode in the answer"
    stories = [
        Hypothesis("result-before-cycle", gettext("the result is wrong only until a cycle has ended"),
                   Status.CONFIRMED if legal else Status.RULED_OUT, exp.name),
        Hypothesis("result-first-on-connection", gettext("every first result request of a connection is answered "
                                                         "wrongly"), Status.RULED_OUT if legal else Status.CONSISTENT,
                   exp.name)]
    original = cause.title
    cause.confirmed = legal
    if not legal:
        cause.title = titles.unconfirmed(original)
    else:
        cause.title = title_for(first if isinstance(first, int) else None, int(now or 0))
    cause.diagnosis = {"confirmed": legal, "mechanism": RESULT_BEFORE_CYCLE if legal else None,
                       "catalogue_title": original, "detail": {"first": first, "now": now},
                       "hypotheses": [h.to_dict() for h in stories], "experiments": [exp.to_dict()]}

"""The baseline every other case stands on: the box answers a NONE request (A4) on a
fresh connection within time_out (T1), in the profile of this run.

It runs first and even when the box looks dead, so a box that answers nothing (or
speaks another profile) FAILs here with one clear message, and the other cases end
INCONCLUSIVE quickly instead of each waiting out its own time_out.
"""

from __future__ import annotations

from conformance.protocol import Action, encode, request
from conformance.suite import (
    Answer,
    CaseContext,
    Level,
    Requirement,
    Signature,
    answered_allowed,
    answers_none,
    case,
    responsive,
)


@case("T1-00", ["A4", "T1"], Level.MUST, "Baseline: NONE is answered 0000 on a fresh connection within time_out",
      "NONE answered with action 00 and error 0000 within time_out", needs=("any-profile", "always"),
      checks={"": Requirement(("A4", "T1"), "action 00 is answered with action 00 and error 0000 within time_out",
                              accept=answered_allowed(Action.NONE)),
              "unanswered": Requirement(("A4", "T1"), "the box does not answer a NONE request in this profile, so every "
                                        "other case is INCONCLUSIVE (if the box is up, PROFILE-01 tells which profile "
                                        "it appears to use)")})
def test_baseline(isight: CaseContext) -> None:
    outcome = isight.session.baseline
    if outcome is None:  # the plugin checks once per session; be robust if it did not
        outcome = isight.check_alive()
    if isinstance(outcome, Answer):
        isight.latencies_ms.append(outcome.latency_s * 1000)
    if answers_none(outcome):
        return
    isight.last_sent = encode(request(Action.NONE), isight.profile)
    if responsive(outcome):  # it answers, wrongly: judged like any answer (a malformed one fails on its format)
        isight.judge(outcome)
    raise isight.broken("unanswered", expected="NONE answered 0000 within time_out", observed=outcome.describe(),
                        sent=isight.last_sent, received=outcome.raw, signature=Signature.unreachable("session start"))

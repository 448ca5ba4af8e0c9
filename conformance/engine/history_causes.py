"""Root causes of the box's history: the same request answered wrongly at one point of the run and right at another.

The catalogue sends some requests at a chosen point of the box's history. The run's first result request (27)
goes out at session start, before the suite has run any cycle (E3-02). A box that answers it with a ResultCode
E3 does not allow while it answers the same bytes later (E3-01, after the suite's cycles) has a defect of its
state, not of the request's bytes: :func:`history_causes` claims that pair as one root cause, and the diagnose
phase (:mod:`conformance.diagnose.result_state`) asks again now, on a fresh connection.
"""

from __future__ import annotations

from collections.abc import Sequence

from ..i18n import gettext
from ..model.verdicts import CaseResult, RootCause, Verdict
from .patterns import Claim, evidence_of

#: the root-cause kind this module makes
RESULT_BEFORE_CYCLE = "result-before-cycle"
#: (the case sent before any cycle, the case sending the same request later)
FIRST, LATER = "E3-02", "E3-01"


def history_causes(cases: Sequence[CaseResult]) -> list[Claim]:
    by_id = {c.id: c for c in cases}
    first, later = by_id.get(FIRST), by_id.get(LATER)
    if first is None or later is None or first.verdict is not Verdict.FAIL or later.verdict is not Verdict.PASS:
        return []
    code, now = first.details.get("result_code"), later.details.get("result_code")
    seen = gettext("ResultCode {code}").format(code=code) if code is not None else gettext("a malformed answer")
    title = gettext("Answers the result request (27) with {seen} at session start, before any cycle, and with "
                    "ResultCode {now} after the suite's cycles ({later}): E3 allows only 1, 2, 10, 20, 202, 400 or "
                    "409").format(seen=seen, now=now, later=LATER)
    return [(RootCause("", ("E3",), title, evidence_of(first), kind=RESULT_BEFORE_CYCLE), [first])]

"""Golden vectors replayed against the box: every ``robot-to-box`` TCP vector of
``vectors/frames/*.json`` is sent as is, on its own connection.

* ``valid`` (A1-10): a well-formed request, answered with its action and 0000
  (CycleOn 0001 is "not ready": INCONCLUSIVE; CycleOff 0002 is a legal answer).
* ``invalid`` (R1-10): never 0000 (R1/A5/A3 MUST); a B3–B5 parse error of 23/24/25
  SHOULD get the action's error (A3). A vector cut short (the header announces more
  bytes than it carries) is sent, then our side is closed: "the stream ends after it".
* ``acceptable`` (R1-11): INFORMATIONAL, what the box did.

The vectors were written for a receiver with a big-endian profile and the group's
first index: a vector with blocks from a group whose first index differs from the
run's is SKIP, and an ``invalid`` vector the run's (lenient) profile accepts is only
recorded. ``Extension`` vectors need E (else SKIP; invalid ones stay invalid).
"""

from __future__ import annotations

import pytest

from conformance.evidence.vectors_file import Vector
from conformance.harness.client import Answer
from conformance.protocol import (
    Action,
    ErrorCode,
    peek_action,
    peek_header,
    request,
)
from conformance.suite import NOT_OK, CaseContext, Expect, Level, Requirement, answered, case
from conformance.suite.vector_checks import (
    announced_len,
    applicable,
    named_error,
    params,
    restore_idle,
    run_profile_accepts,
    send_cut_short,
    valid_expect,
)

# -- valid -----------------------------------------------------------------------------------------


@case("A1-10", ["A1", "A4", "B1", "B2", "B3", "B4", "B5"], Level.MUST, "Valid golden vectors are answered 0000",
      "answered with the vector's action and 0000 (CycleOn 0001: INCONCLUSIVE, S2; CycleOff 0002 allowed, A3; "
      "ProgIdx: the same index or 409, E2)",
      checks={"prep": Requirement(("S3",), "{prep.name} brings the box to the state the vector expects",
                                  inconclusive=Expect("not answered", lambda o: not isinstance(o, Answer)),
                                  inconclusive_text="could not prepare the box's cycle state with {prep.name}"),
              "started": Requirement(("S2",), "a cycle is started before the CycleOff vector",
                                     inconclusive=Expect("not answered 0000",
                                                         lambda o: not (isinstance(o, Answer) and not o.frame.error_code)),
                                     inconclusive_text="S2: could not start a cycle before the CycleOff vector"),
              "": Requirement(("A1",), "the well-formed request of vector {vector.name} is answered 0000",
                              accept=lambda vector, action, conflict="block", **_: valid_expect(vector, action,
                                                                                                conflict),
                              inconclusive=lambda action, **_: answered(action, [ErrorCode.NOT_READY]) if action is Action.CYCLE_ON else None,
                              inconclusive_text="S2: CycleOn answered 0001 (box not ready)")}, shares_box=True)
@pytest.mark.parametrize("vector", params("valid"))
def test_valid_vector(isight: CaseContext, vector: Vector | None) -> None:
    v = applicable(isight, vector)
    head = peek_header(v.data)
    assert head is not None  # a valid vector is a whole frame
    action = Action(head.action)
    conn = isight.connect()
    if action in (Action.CYCLE_ON, Action.CYCLE_OFF):  # judge from a known state (S3: CycleOn twice MAY fail)
        prep = Action.CYCLE_OFF if action is Action.CYCLE_ON else Action.CYCLE_ON
        before = conn.request(request(prep), f"preparation: {prep.name}, so the vector meets the state it expects")
        isight.judge(before, "prep", sent=b"", prep=prep)
        if prep is Action.CYCLE_ON:
            isight.judge(before, "started", sent=b"")
    outcome = conn.request(v.data, f"golden vector {v.name}: {v.comment[:80]}")
    if isinstance(outcome, Answer):
        isight.latencies_ms.append(outcome.latency_s * 1000)
    restore_idle(isight, outcome, conn)  # a CycleOn it took: off again, whatever the verdict
    isight.judge(outcome, sent=v.data, vector=v, action=action, conflict=isight.profile.progidx_conflict)
    assert isinstance(outcome, Answer)
    code = outcome.frame.error_code
    if action is Action.CYCLE_OFF and code == 2:
        isight.inform("CycleOff answered 0002: the box could not close the detection (A3)")
    elif action is Action.VISION_RESULT and code:
        isight.inform(f"result request answered with error field {code:04X} (E3 names none)")


# -- invalid ---------------------------------------------------------------------------------------


@case("R1-10", ["R1", "A5", "A3", "B5", "F5"], Level.MUST, "Invalid golden vectors are never answered 0000",
      "not 0000 (MUST: silence, a non-zero error or a close); a B3-B5 parse error of 23/24/25 answered 1001/1002 (SHOULD, A3)",
      checks={"": Requirement(("R1",), "vector {vector.name} breaks {clauses} and MUST NOT be answered 0000", accept=NOT_OK,
                              should=lambda named, action, **_: None if named is None else answered(action, [named]),
                              should_clauses=("A3",), should_text="a parse error under {clause} SHOULD be answered {named:04X}")},
      shares_box=True)
@pytest.mark.parametrize("vector", params("invalid"))
def test_invalid_vector(isight: CaseContext, vector: Vector | None) -> None:
    v = applicable(isight, vector)
    if len(v.data) < announced_len(v.data):
        outcome = send_cut_short(isight, v.data)
        named = None  # the box may be waiting for the rest, then sees the end of the stream (F5)
    else:
        outcome = isight.send_malformed(v.data, f"golden vector {v.name}: {v.comment[:80]}")
        named = named_error(v)
    restore_idle(isight, outcome, None)
    if run_profile_accepts(isight, v):
        isight.inform(f"this run's profile ({isight.profile.describe()}) reads vector {v.name} as valid; "
                      f"the box {outcome.describe()}")
        return
    isight.judge(outcome, sent=v.data, vector=v, clauses=", ".join(v.clauses), clause=v.clauses[0], named=named,
                 action=peek_action(v.data))


# -- acceptable ------------------------------------------------------------------------------------


@case("R1-11", ["R1", "B4", "F6", "A3"], Level.MAY, "Acceptable golden vectors: what the box did",
      "recorded: accepting (0000) or rejecting are both allowed (a SHOULD, or a point PROTOCOL.md leaves open)",
      shares_box=True)
@pytest.mark.parametrize("vector", params("acceptable"))
def test_acceptable_vector(isight: CaseContext, vector: Vector | None) -> None:
    v = applicable(isight, vector)
    outcome = isight.send_malformed(v.data, f"golden vector {v.name} ({', '.join(v.flags)}): {v.comment[:80]}")
    restore_idle(isight, outcome, None)
    took = isinstance(outcome, Answer) and outcome.frame.error_code == 0
    isight.details["accepted"] = took
    isight.inform(f"{', '.join(v.flags)}: the box {'accepted' if took else 'did not accept'} vector {v.name} "
                  f"(it {outcome.describe()})")

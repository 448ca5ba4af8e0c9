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

import socket
from typing import Any

import pytest

from conformance.evidence.vectors_file import REPO_VECTORS, Vector, load_dir
from conformance.protocol import (
    ACTION_ERROR,
    HEADER_LEN,
    Action,
    ErrorCode,
    ProtocolError,
    TransferType,
    Transport,
    codec_for,
    peek_action,
    peek_header,
    request,
)
from conformance.protocol.answers import Cycle
from conformance.protocol.constants import CHECK_LEN
from conformance.suite import (
    ALONE_MARK,
    NOT_OK,
    Answer,
    CaseContext,
    Expect,
    Kind,
    Level,
    Outcome,
    Requirement,
    Skip,
    answered,
    answered_allowed,
    case,
    stateless_frame,
)

# -- the family's helpers: Helpers of the golden-vector cases (conformance/cases/vector_replay.py): loading the vectors, applicability, what each may be answered.
VECTORS_DIR = REPO_VECTORS / "frames"


def load() -> tuple[list[Vector], str]:
    try:
        found = load_dir(VECTORS_DIR)
    except (OSError, ValueError, KeyError) as exc:
        return [], f"the golden vectors in {VECTORS_DIR} cannot be read: {exc}"
    mine = [v for v in found if v.transport is Transport.TCP and v.direction is TransferType.ROBOT_TO_BOX]
    return mine, "" if mine else f"no robot-to-box TCP golden vectors found in {VECTORS_DIR} (not packaged?)"


VECTORS, MISSING = load()


def params(result: str) -> list[Any]:
    """The vectors of one kind. A valid or acceptable one that may change the box's state (a CycleOn, a
    ProgIdx, two frames) runs alone; an invalid one is refused by a legal box, whatever its action."""
    chosen = [pytest.param(v, id=v.name, marks=() if result == "invalid" or stateless_frame(v.data)
                           else getattr(pytest.mark, ALONE_MARK)) for v in VECTORS if v.result == result]
    return chosen or [pytest.param(None, id="no-vectors")]


def applicable(isight: CaseContext, v: Vector | None) -> Vector:
    """The vector, or Skip with the reason it cannot be judged in this run."""
    if v is None:
        raise Skip(MISSING or "no golden vectors of this kind")
    isight.details["vector"] = {"file": v.file, "tcId": v.tc_id, "comment": v.comment, "clauses": list(v.clauses),
                                "flags": list(v.flags), "result": v.result, "hex": v.data.hex()}
    prof = isight.profile
    if prof.byte_order != "big" or prof.float_byte_order != "big":
        raise Skip(f"the vectors are big-endian (F4/B4); this run's profile has byte_order={prof.byte_order}, "
                   f"float_byte_order={prof.float_byte_order}")
    other_index = v.other_first_index(prof)
    if other_index is not None:
        raise Skip(other_index)
    if "Extension" in v.flags and v.result != "invalid" and not isight.session.detect_extension(isight.transcript):
        raise Skip(f"extension vector and the box lacks E ({isight.session.extension_how}); A5-02 covers 26/27 then")
    return v


def run_profile_accepts(isight: CaseContext, v: Vector) -> bool:
    """Does the run's profile read these bytes as a valid request (e.g. a lenient profile)?"""
    try:
        codec_for(isight.profile).parse(v.data, Transport.TCP, TransferType.ROBOT_TO_BOX)
    except ProtocolError:
        return False
    return True


def announced_len(data: bytes) -> int:
    head = peek_header(data)
    return HEADER_LEN + CHECK_LEN if head is None else head.frame_length


def restore_idle(isight: CaseContext, outcome: Outcome, conn: Any) -> None:
    """A CycleOn the box took (0000) leaves the shared cycle on: switch it off again."""
    if isinstance(outcome, Answer) and outcome.frame.action == Action.CYCLE_ON and outcome.frame.error_code == 0:
        target = conn if conn is not None and conn.closed_by_peer is None else isight.connect("cleanup")
        target.request(request(Action.CYCLE_OFF), "cleanup: CycleOff, so the box is idle again (not judged)")


def prog_idx_expect(value: int, conflict: str) -> Expect:
    """E2: the same index, or 409: in the block, or (``--progidx-conflict error-code``) in the error field."""
    def ok(o: Outcome) -> bool:
        if not isinstance(o, Answer) or o.frame.action != Action.PROG_IDX or not o.frame.blocks:
            return False
        got, err = getattr(o.frame.blocks[0], "value", None), o.frame.error_code
        in_error = conflict == "error-code" and err in (409, 0x0409)  # as extension_e's CONFLICT_ERRORS
        return (got == value and err == 0) or (got == 409 and err in (0, 409)) or in_error

    where = "409 in the error field" if conflict == "error-code" else "409"
    return Expect(f"answered PROG_IDX carrying {value} with error 0000, or {where} (E2)", ok)


def valid_expect(v: Vector, action: Action, conflict: str = "block") -> Expect:
    if action is Action.CYCLE_ON:
        return answered_allowed(action, Cycle.IDLE)
    if action is Action.CYCLE_OFF:
        return answered_allowed(action, Cycle.ON)
    if action is Action.PROG_IDX:
        return prog_idx_expect(v.frame["blocks"][0]["value"] if v.frame else 0, conflict)
    if action is Action.VISION_RESULT:
        return answered(action)
    return answered_allowed(action)


def named_error(v: Vector) -> int | None:
    """A3: the error PROTOCOL.md names for this vector's parse error, if any."""
    head = peek_header(v.data)
    if head is None or not (head.start_ok and head.version_ok and head.is_request):
        return None
    if not v.clauses or v.clauses[0] not in ("B1", "B2", "B3", "B4", "B5"):
        return None
    try:
        return ACTION_ERROR.get(Action(head.action))
    except ValueError:
        return None


def send_cut_short(isight: CaseContext, data: bytes) -> Outcome:
    """A vector shorter than its header announces: send it, end the stream, see what follows."""
    isight.needs_liveness = True
    isight.last_sent = data
    conn = isight.connect("malformed")
    if not conn.send(data, "vector cut short: the header announces more bytes than follow"):
        return conn.closed_by_peer or conn.next_outcome(0)
    if conn.sock is not None:
        try:
            conn.sock.shutdown(socket.SHUT_WR)
            isight.transcript.add(conn.conn_id, Kind.CLOSE, note="end of stream after the vector (half-close)")
        except OSError:
            pass
    return conn.next_outcome()


# -- the cases

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

"""B: data blocks (pose and tolerance layout, indexes, floats, the shape each action fixes).

Well-formed requests are built from the run's profile (first index, float byte order),
so a box read with ``--first-index 1`` is tested on its own terms. Malformed requests
go through ``isight.send_malformed`` (a probe bounds the wait, R2 is checked after).
A3 fixes what a parse error earns: never 0000 (MUST), the action's error (SHOULD).
"""

from __future__ import annotations

import pytest

from conformance.harness.client import Answer
from conformance.protocol import (
    Action,
    Header,
    encode_raw,
    pose_blocks,
    request,
    tolerance_blocks,
)
from conformance.suite import NOT_OK, CaseContext, Level, Requirement, answered_allowed, case
from conformance.suite.block_requests import (
    ACTION_IDS,
    EDGE_FLOATS,
    INDEX_ERRORS,
    NON_FINITE,
    PARSE_ERROR,
    POSE,
    REG,
    SHAPE_CASES,
    TOL,
    block_bytes,
    data_request,
    named_error,
    sample_poses,
    with_odd_float,
)

# -- B1 / B2: layout and block counts ------------------------------------------------------------


@case("B1-01", ["B1", "B3", "A1", "S3"], Level.MUST, "Pose and register-pose requests with 1, 3 and 255 blocks are answered 0000",
      "answered with the request's action (23 or 24) and error 0000",
      checks={"": Requirement(("A1", "B1"), "a well-formed {action.name} request with {count} block(s) is answered 0000",
                              accept=lambda action, **_: answered_allowed(action))}, shares_box=True)
@pytest.mark.parametrize("action", [POSE, REG], ids=["pose", "register-pose"])
@pytest.mark.parametrize("count", [1, 3, 255])
def test_pose_block_counts(isight: CaseContext, action: Action, count: int) -> None:
    frame = request(action, pose_blocks(sample_poses(count), isight.profile.first_index))
    outcome = isight.exchange(frame, f"{action.name} request with {count} pose block(s) (L=25)")
    isight.judge(outcome)


@case("B1-02", ["B1", "B5", "A3", "R1"], Level.MUST, "A pose request whose block length is not 25 is not answered 0000",
      "not 0000 (MUST); answered 1001 (SHOULD, A3)", checks={"": PARSE_ERROR}, shares_box=True)
@pytest.mark.parametrize("action", [POSE, REG], ids=["pose", "register-pose"])
@pytest.mark.parametrize("length", [24, 26], ids=["L24", "L26"])
def test_pose_wrong_length(isight: CaseContext, action: Action, length: int) -> None:
    block = block_bytes(action, isight.profile.first_index, isight.profile)
    body = block[:length] if length < 25 else block + b"\x00" * (length - 25)
    bad = data_request(action, [isight.profile.first_index], isight.profile, length=length, body=body)
    outcome = isight.send_malformed(bad, f"{action.name} request with block length {length}")
    isight.judge(outcome, what=f"{action.name} request with L={length}")


@case("B2-01", ["B2", "B3", "A1", "S3"], Level.MUST, "Tolerance requests with 1, 3 and 255 blocks are answered 0000",
      "answered TOLERANCE with error 0000",
      checks={"": Requirement(("A1", "B2"), "a well-formed tolerance request with {count} block(s) is answered 0000",
                              accept=answered_allowed(TOL))}, shares_box=True)
@pytest.mark.parametrize("count", [1, 3, 255])
def test_tolerance_block_counts(isight: CaseContext, count: int) -> None:
    values = [0.25 + 0.5 * i for i in range(count)]
    frame = request(TOL, tolerance_blocks(values, isight.profile.first_index))
    outcome = isight.exchange(frame, f"tolerance request with {count} block(s) (L=5)")
    isight.judge(outcome)


@case("B2-02", ["B2", "B5", "A3", "R1"], Level.MUST, "A tolerance request whose block length is not 5 is not answered 0000",
      "not 0000 (MUST); answered 1002 (SHOULD, A3)", checks={"": PARSE_ERROR}, shares_box=True)
@pytest.mark.parametrize("length", [4, 6, 25], ids=["L4", "L6", "L25"])
def test_tolerance_wrong_length(isight: CaseContext, length: int) -> None:
    first = isight.profile.first_index
    if length == 25:  # a pose-sized block announced as a tolerance block (type 02)
        body = block_bytes(POSE, first, isight.profile)
    else:
        block = block_bytes(TOL, first, isight.profile)
        body = block[:length] if length < 5 else block + b"\x00" * (length - 5)
    bad = data_request(TOL, [first], isight.profile, length=length, body=body)
    outcome = isight.send_malformed(bad, f"tolerance request (type 02) with block length {length}")
    isight.judge(outcome, action=TOL, what=f"tolerance request with L={length}")


# -- B3: indexes ---------------------------------------------------------------------------------


@case("B3-01", ["B3"], Level.MAY, "Which first block index the box expects (0 or 1)",
      "recorded: how the box answers a one-pose request indexed 00 and one indexed 01", shares_box=True)
def test_first_index_discovery(isight: CaseContext) -> None:
    seen: dict[int, str] = {}
    accepts: list[int] = []
    for first in (0, 1):
        data = data_request(POSE, [first], isight.profile)
        if first == isight.profile.first_index:
            outcome = isight.exchange(data, f"pose request, single block indexed {first:02x} (the profile's reading)")
        else:
            outcome = isight.send_malformed(data, f"pose request, single block indexed {first:02x} (the other reading)")
        seen[first] = outcome.describe()
        if isinstance(outcome, Answer) and outcome.frame.action == POSE and outcome.frame.error_code == 0:
            accepts.append(first)
    isight.details["first_index"] = {"profile": isight.profile.first_index, "accepted": accepts}
    if accepts == [isight.profile.first_index]:
        verdict = f"the box expects first index {accepts[0]}, as the profile says"
    elif len(accepts) == 1:
        verdict = (f"the box expects first index {accepts[0]}, the profile says {isight.profile.first_index}: "
                   f"rerun with --first-index {accepts[0]}")
    elif accepts:
        verdict = "the box accepts both 0 and 1 as the first index"
    else:
        verdict = "the box accepted neither reading"
    isight.inform(f"{verdict} (index 00: {seen[0]}; index 01: {seen[1]})")


@case("B3-02", ["B3", "A3", "R1"], Level.MUST, "Block indexes with a gap, a repeat, a wrong start or descending are a parse error",
      "not 0000 (MUST); answered 1001 for 23/24, 1002 for 25 (SHOULD, A3)", checks={"": PARSE_ERROR}, shares_box=True)
@pytest.mark.parametrize("action", [POSE, REG, TOL], ids=list(ACTION_IDS.values()))
@pytest.mark.parametrize("kind,relative", INDEX_ERRORS, ids=[k for k, _ in INDEX_ERRORS])
def test_index_errors(isight: CaseContext, action: Action, kind: str, relative: list[int] | None) -> None:
    first = isight.profile.first_index
    indexes = [1 - first] if relative is None else [first + r for r in relative]
    bad = data_request(action, indexes, isight.profile)
    what = f"{action.name} request with block indexes {', '.join(f'{i:02x}' for i in indexes)} (profile's first index {first})"
    outcome = isight.send_malformed(bad, what)
    if relative is None and not isight.profile.strict:
        isight.inform(f"lenient profile: first index 0 and 1 are both accepted; to {what} the box {outcome.describe()}")
        return
    isight.judge(outcome, what=what)


# -- B4: floats ----------------------------------------------------------------------------------


@case("B4-01", ["B4", "A3"], Level.SHOULD, "NaN and infinity in a pose or tolerance are treated as a parse error",
      "answered 1001 (pose) / 1002 (tolerance); 0000 is NON-STRICT (B4 SHOULD), so are silence and a close (A3 SHOULD)",
      checks={"": Requirement(("B4",), "NaN or infinity SHOULD be treated as a parse error (not answered 0000)", accept=NOT_OK,
                              should=named_error,
                              should_clauses=("A3",), should_text="a parse error in a {action.name} request SHOULD be answered with the "
                                          "action's error")}, shares_box=True)
@pytest.mark.parametrize("action,bits,where", [p[1:] for p in NON_FINITE], ids=[p[0] for p in NON_FINITE])
def test_non_finite(isight: CaseContext, action: Action, bits: int, where: tuple[int, int]) -> None:
    bad = with_odd_float(action, bits, where, isight.profile)
    what = f"{action.name} request with float {bits:08X} in block {where[0]}, value {where[1]}"
    outcome = isight.send_malformed(bad, what)
    if not isight.profile.strict:
        isight.inform(f"lenient profile (B4 SHOULD not enforced): to {what} the box {outcome.describe()}")
        return
    isight.judge(outcome)


@case("B4-02", ["B4", "A1", "A3"], Level.MUST, "Legal float32 edge values (-0.0, subnormals, max) are accepted",
      "answered with the request's action and 0000: the request is well-formed",
      checks={"": Requirement(("A1", "A3", "B4"), "float32 {bits:08X} is a legal value; the well-formed {action.name} request is "
                              "answered 0000", accept=lambda action, **_: answered_allowed(action))}, shares_box=True)
@pytest.mark.parametrize("action", [POSE, TOL], ids=["pose", "tolerance"])
@pytest.mark.parametrize("bits", [b for _, b in EDGE_FLOATS], ids=[n for n, _ in EDGE_FLOATS])
def test_edge_floats(isight: CaseContext, action: Action, bits: int) -> None:
    per = 6 if action is POSE else 1
    data = data_request(action, [isight.profile.first_index], isight.profile, [[bits] * per])
    isight.judge(isight.exchange(data, f"{action.name} request, every float {bits:08X}"))


# -- B5: the shape each action fixes -------------------------------------------------------------


@case("B5-01", ["B5", "A3", "R1"], Level.MUST, "A request whose block type, count or length does not fit its action is not answered 0000",
      "not 0000 (MUST); for 23/24 answered 1001, for 25 answered 1002 (SHOULD, A3); "
      "for 00/01/02 PROTOCOL.md names no code: a non-zero error, silence or a close", checks={"": PARSE_ERROR},
      shares_box=True)
@pytest.mark.parametrize("action,btype,count,length,body_kind", [c[1:] for c in SHAPE_CASES], ids=[c[0] for c in SHAPE_CASES])
def test_wrong_shape(isight: CaseContext, action: int, btype: int, count: int, length: int, body_kind: str) -> None:
    first = isight.profile.first_index
    body = b""
    if body_kind:
        kind = POSE if body_kind == "pose" else TOL
        body = b"".join(block_bytes(kind, first + i, isight.profile) for i in range(count))
    header = Header(action=action, block_type=btype, block_count=count, block_length=length)
    bad = encode_raw(header, body, profile=isight.profile)
    what = f"{Action(action).name} request with block type {btype:02x}, N={count}, L={length}"
    isight.judge(isight.send_malformed(bad, what), what=what)

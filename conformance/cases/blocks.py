"""B: data blocks (pose and tolerance layout, indexes, floats, the shape each action fixes).

Well-formed requests are built from the run's profile (first index, float byte order),
so a box read with ``--first-index 1`` is tested on its own terms. Malformed requests
go through ``isight.send_malformed`` (a probe bounds the wait, R2 is checked after).
A3 fixes what a parse error earns: never 0000 (MUST), the action's error (SHOULD).
"""

from __future__ import annotations

import pytest

from conformance.protocol import (
    ACTION_ERROR,
    BLOCK_LEN,
    REQUEST_SHAPE,
    Action,
    Header,
    Profile,
    codec_for,
    encode_raw,
    request,
)
from conformance.protocol.constants import EDGE_FLOAT32, f32_bits
from conformance.suite import (
    NOT_OK,
    Answer,
    CaseContext,
    Expect,
    Level,
    Requirement,
    answered,
    answered_allowed,
    case,
)

# -- the family's helpers: Helpers of the B cases (conformance/cases/blocks.py): block bytes, data requests, index errors, odd floats and shapes.
POSE, REG, TOL = Action.POSE, Action.REGISTER_POSE, Action.TOLERANCE

#: block type and length of the blocks each data action carries (B1, B2, B5): the protocol's shape table
SHAPE = {a: (REQUEST_SHAPE[a].block_type, BLOCK_LEN[REQUEST_SHAPE[a].block_type]) for a in (POSE, REG, TOL)}

ACTION_IDS = {POSE: "pose", REG: "register-pose", TOL: "tolerance"}


def f32(bits: int, profile: Profile) -> bytes:
    return bits.to_bytes(4, profile.float_byte_order)


def value_bits(value: float) -> int:
    return f32_bits(value)


def block_bytes(action: Action, index: int, profile: Profile, floats: list[int] | None = None) -> bytes:
    """One well-laid-out block for ``action``: index byte + float32s given as bit patterns."""
    count = 6 if action in (POSE, REG) else 1
    if floats is None:
        floats = [value_bits(100.0 * (index + 1) + j) for j in range(count)]
    return bytes([index & 0xFF]) + b"".join(f32(b, profile) for b in floats)


def data_request(
    action: Action, indexes: list[int], profile: Profile, floats: list[list[int]] | None = None,
    *, block_type: int | None = None, length: int | None = None, body: bytes | None = None,
) -> bytes:
    """A 23/24/25 request with blocks at ``indexes`` (any order); header fields may be overridden."""
    btype, blen = SHAPE[action]
    if body is None:
        body = b"".join(
            block_bytes(action, i, profile, floats[k] if floats else None) for k, i in enumerate(indexes)
        )
    header = Header(
        action=action, block_type=btype if block_type is None else block_type, block_count=len(indexes),
        block_length=blen if length is None else length,
    )
    return encode_raw(header, body, profile=profile)


def sample_poses(n: int) -> list[tuple[float, ...]]:
    return [(500.0 + i, -20.5 * i, 300.25, 180.0, -0.5 * i, 90.0) for i in range(n)]


def named_error(action: int, **_: object) -> Expect | None:
    error = ACTION_ERROR.get(Action(action))
    return None if error is None else answered(action, [error])


#: A3: a parse error MUST NOT be answered 0000 and SHOULD get the action's error (where A3 names one)
PARSE_ERROR = Requirement(("A3",), "a {what} is a parse error and MUST NOT be answered 0000", accept=NOT_OK,
                          should=named_error, should_clauses=("A3",), should_text="a {what} SHOULD be answered with the action's error")

#: (id, indexes relative to the first index); "wrong-start" is the other reading of B3
INDEX_ERRORS = [
    ("gap", [0, 2]),
    ("late-gap", [0, 1, 3]),
    ("repeat", [0, 0]),
    ("descending", [1, 0]),
    ("wrong-start", None),
]

QNAN, SNAN, NEG_NAN, INF, NEG_INF = 0x7FC00000, 0x7F800001, 0xFFC00000, 0x7F800000, 0xFF800000

#: (id, action, position of the odd value: (block, float)); the other floats are ordinary
NON_FINITE = [
    ("pose-qnan-x", POSE, QNAN, (0, 0)),
    ("pose-snan-y", POSE, SNAN, (0, 1)),
    ("pose-inf-z", POSE, INF, (0, 2)),
    ("pose-neginf-r-second-block", POSE, NEG_INF, (1, 5)),
    ("register-pose-negnan-w", REG, NEG_NAN, (0, 3)),
    ("tolerance-qnan", TOL, QNAN, (0, 0)),
    ("tolerance-inf", TOL, INF, (0, 0)),
    ("tolerance-neginf", TOL, NEG_INF, (0, 0)),
]


def with_odd_float(action: Action, bits: int, where: tuple[int, int], profile: Profile) -> bytes:
    block_no, pos = where
    per = 6 if action in (POSE, REG) else 1
    floats = [[value_bits(10.0 * b + j) for j in range(per)] for b in range(block_no + 1)]
    floats[block_no][pos] = bits
    indexes = [codec_for(profile).block_index(b) for b in range(block_no + 1)]
    return data_request(action, indexes, profile, floats)


#: legal float32 values a box must take: (id, bit pattern)
EDGE_FLOATS = EDGE_FLOAT32

T00, T01, T02, T03 = 0x00, 0x01, 0x02, 0x03


def shape_cases() -> list[tuple[str, int, int, int, int, str]]:
    """(id, action, block type, N, L, body kind) for every wrong combination we send."""
    return [
        ("none-with-pose-block", Action.NONE, T01, 1, 25, "pose"),
        ("none-L25", Action.NONE, T00, 0, 25, ""),
        ("none-N1-L0", Action.NONE, T00, 1, 0, ""),
        ("cycle-on-with-pose-block", Action.CYCLE_ON, T01, 1, 25, "pose"),
        ("cycle-on-type02-empty", Action.CYCLE_ON, T02, 0, 0, ""),
        ("cycle-off-with-tolerance-block", Action.CYCLE_OFF, T02, 1, 5, "tolerance"),
        ("cycle-off-L5", Action.CYCLE_OFF, T00, 0, 5, ""),
        ("pose-N0", POSE, T01, 0, 25, ""),
        ("pose-empty", POSE, T00, 0, 0, ""),
        ("pose-with-tolerance-block", POSE, T02, 1, 5, "tolerance"),
        ("pose-type00-with-pose-block", POSE, T00, 1, 25, "pose"),
        ("pose-type03-block", POSE, T03, 1, 5, "tolerance"),
        ("pose-type04", POSE, 0x04, 1, 25, "pose"),
        ("register-pose-N0", REG, T01, 0, 25, ""),
        ("register-pose-with-tolerance-block", REG, T02, 1, 5, "tolerance"),
        ("tolerance-N0", TOL, T02, 0, 5, ""),
        ("tolerance-empty", TOL, T00, 0, 0, ""),
        ("tolerance-type01-L5", TOL, T01, 1, 5, "tolerance"),
        ("tolerance-with-pose-block", TOL, T01, 1, 25, "pose"),
    ]


SHAPE_CASES = shape_cases()


# -- the cases

# -- B1 / B2: layout and block counts ------------------------------------------------------------


@case("B1-01", ["B1", "B3", "A1", "S3"], Level.MUST, "Pose and register-pose requests with 1, 3 and 255 blocks are answered 0000",
      "answered with the request's action (23 or 24) and error 0000",
      checks={"": Requirement(("A1", "B1"), "a well-formed {action.name} request with {count} block(s) is answered 0000",
                              accept=lambda action, **_: answered_allowed(action))}, shares_box=True)
@pytest.mark.parametrize("action", [POSE, REG], ids=["pose", "register-pose"])
@pytest.mark.parametrize("count", [1, 3, 255])
def test_pose_block_counts(isight: CaseContext, action: Action, count: int) -> None:
    frame = request(action, isight.codec.pose_blocks(sample_poses(count)))
    outcome = isight.exchange(frame, f"{action.name} request with {count} pose block(s) (L=25)")
    isight.judge(outcome)


@case("B1-02", ["B1", "B5", "A3", "R1"], Level.MUST, "A pose request whose block length is not 25 is not answered 0000",
      "not 0000 (MUST); answered 1001 (SHOULD, A3)", checks={"": PARSE_ERROR}, shares_box=True)
@pytest.mark.parametrize("action", [POSE, REG], ids=["pose", "register-pose"])
@pytest.mark.parametrize("length", [24, 26], ids=["L24", "L26"])
def test_pose_wrong_length(isight: CaseContext, action: Action, length: int) -> None:
    first = isight.codec.block_index(0)
    block = block_bytes(action, first, isight.profile)
    body = block[:length] if length < 25 else block + b"\x00" * (length - 25)
    bad = data_request(action, [first], isight.profile, length=length, body=body)
    outcome = isight.send_malformed(bad, f"{action.name} request with block length {length}")
    isight.judge(outcome, what=f"{action.name} request with L={length}")


@case("B2-01", ["B2", "B3", "A1", "S3"], Level.MUST, "Tolerance requests with 1, 3 and 255 blocks are answered 0000",
      "answered TOLERANCE with error 0000",
      checks={"": Requirement(("A1", "B2"), "a well-formed tolerance request with {count} block(s) is answered 0000",
                              accept=answered_allowed(TOL))}, shares_box=True)
@pytest.mark.parametrize("count", [1, 3, 255])
def test_tolerance_block_counts(isight: CaseContext, count: int) -> None:
    values = [0.25 + 0.5 * i for i in range(count)]
    frame = request(TOL, isight.codec.tolerance_blocks(values))
    outcome = isight.exchange(frame, f"tolerance request with {count} block(s) (L=5)")
    isight.judge(outcome)


@case("B2-02", ["B2", "B5", "A3", "R1"], Level.MUST, "A tolerance request whose block length is not 5 is not answered 0000",
      "not 0000 (MUST); answered 1002 (SHOULD, A3)", checks={"": PARSE_ERROR}, shares_box=True)
@pytest.mark.parametrize("length", [4, 6, 25], ids=["L4", "L6", "L25"])
def test_tolerance_wrong_length(isight: CaseContext, length: int) -> None:
    first = isight.codec.block_index(0)
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
    data = data_request(action, [isight.codec.block_index(0)], isight.profile, [[bits] * per])
    isight.judge(isight.exchange(data, f"{action.name} request, every float {bits:08X}"))


# -- B5: the shape each action fixes -------------------------------------------------------------


@case("B5-01", ["B5", "A3", "R1"], Level.MUST, "A request whose block type, count or length does not fit its action is not answered 0000",
      "not 0000 (MUST); for 23/24 answered 1001, for 25 answered 1002 (SHOULD, A3); "
      "for 00/01/02 PROTOCOL.md names no code: a non-zero error, silence or a close", checks={"": PARSE_ERROR},
      shares_box=True)
@pytest.mark.parametrize("action,btype,count,length,body_kind", [c[1:] for c in SHAPE_CASES], ids=[c[0] for c in SHAPE_CASES])
def test_wrong_shape(isight: CaseContext, action: int, btype: int, count: int, length: int, body_kind: str) -> None:
    body = b""
    if body_kind:
        kind = POSE if body_kind == "pose" else TOL
        body = b"".join(block_bytes(kind, isight.codec.block_index(i), isight.profile) for i in range(count))
    header = Header(action=action, block_type=btype, block_count=count, block_length=length)
    bad = encode_raw(header, body, profile=isight.profile)
    what = f"{Action(action).name} request with block type {btype:02x}, N={count}, L={length}"
    isight.judge(isight.send_malformed(bad, what), what=what)

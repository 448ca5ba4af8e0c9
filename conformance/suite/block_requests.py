"""Helpers of the B cases (conformance/cases/blocks.py): block bytes, data requests, index errors, odd floats and shapes."""

from __future__ import annotations

from ..protocol import (
    ACTION_ERROR,
    BLOCK_LEN,
    REQUEST_SHAPE,
    Action,
    Header,
    Profile,
    encode_raw,
)
from ..protocol.constants import EDGE_FLOAT32, f32_bits
from .case_judge import NOT_OK, answered
from .record import Expect, Requirement

POSE, REG, TOL = Action.POSE, Action.REGISTER_POSE, Action.TOLERANCE

#: block type and length of the blocks each data action carries (B1, B2, B5): the protocol's shape table
SHAPE = {a: (REQUEST_SHAPE[a].block_type, BLOCK_LEN[REQUEST_SHAPE[a].block_type]) for a in (POSE, REG, TOL)}

ACTION_IDS = {POSE: "pose", REG: "register-pose", TOL: "tolerance"}


def f32(bits: int, profile: Profile) -> bytes:
    return bits.to_bytes(4, profile.float_byte_order)  # type: ignore[arg-type]


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
    indexes = [profile.first_index + b for b in range(block_no + 1)]
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

"""Helpers of the A cases (conformance/cases/actions.py): request sequences, answer shapes, malformed request sets, frames that are not requests."""

from __future__ import annotations

from ..harness.client import Answer, Closed, Malformed, Outcome, TcpConnection
from ..protocol import (
    Action,
    Frame,
    Header,
    Profile,
    encode,
    encode_raw,
    header_field_bytes,
    peek_header,
    pose_blocks,
    request,
    tolerance_blocks,
)
from .case_context import CaseContext
from .case_judge import reply_signature
from .record import Expect, Requirement

POSE, REG, TOL = Action.POSE, Action.REGISTER_POSE, Action.TOLERANCE

ON, OFF, NONE = Action.CYCLE_ON, Action.CYCLE_OFF, Action.NONE

#: A1-01/A1-02: what a sequence of requests is judged by
SEQUENCE = {
    "order": Requirement(("A1",), "every well-formed request is answered with exactly one frame, in request order"),
    "once": Requirement(("A1",), "exactly one answer per request"),
    "taken": Requirement(("A1",), "the box answers every request"),
}


def mixed_requests(first: int) -> list[Frame]:
    """20 mixed requests, no two neighbours with the same action (a duplicate shows)."""
    p = lambda n: request(POSE, pose_blocks([(1.0 + i, 2.0, 3.0, 4.0, 5.0, 6.0) for i in range(n)], first))  # noqa: E731
    r = request(REG, pose_blocks([(10.0, 20.0, 30.0, 0.0, 90.0, 180.0)], first))
    t = lambda n: request(TOL, tolerance_blocks([0.5 * (i + 1) for i in range(n)], first))  # noqa: E731
    n = request(NONE)
    return [n, p(1), t(1), r, n, request(ON), p(1), t(1), p(3), n,
            r, p(1), t(2), n, p(1), request(OFF), p(2), n, t(1), n]


def action_of(outcome: Outcome) -> int | None:
    """The action byte of what the box sent (an answer, or malformed bytes with a readable header)."""
    if isinstance(outcome, Answer):
        return int(outcome.frame.action)
    if isinstance(outcome, Malformed) and outcome.error.header is not None:
        return outcome.error.header.action
    return None


def name(action: int | None) -> str:
    try:
        return Action(action).name if action is not None else "nothing"
    except ValueError:
        return f"0x{action:02X}"


def judge_sequence(isight: CaseContext, conn: TcpConnection, frames: list[Frame], outcomes: list[Outcome], sent: bytes) -> None:
    for i, (frame, outcome) in enumerate(zip(frames, outcomes)):
        got = action_of(outcome)
        if got != frame.action:
            before = ", ".join(name(action_of(o)) for o in outcomes[max(0, i - 2): i + 1])
            raise isight.broken("order", expected=f"answer {i + 1} of {len(frames)} echoes {frame.action.name}",
                                observed=f"{outcome.describe()} (answers {max(1, i - 1)}..{i + 1}: {before})",
                                sent=sent, received=isight.transcript.received(conn.conn_id),
                                signature=reply_signature(outcome, frame.action))
    extra = conn.drain(isight.settings.settle_s)
    if any(not isinstance(o, Closed) for o in extra):
        raise isight.broken("once", expected=f"{len(frames)} answers and nothing more",
                            observed="after them: " + "; ".join(o.describe() for o in extra),
                            sent=sent, received=isight.transcript.received(conn.conn_id))


def shape_problems(raw: bytes, action: int) -> list[str]:
    problems = []
    head = peek_header(raw)
    if head is None:
        return [f"{len(raw)} bytes, expected 14"]
    if not head.is_answer:
        problems.append(f"transfer type {head.transfer_type:02x}, expected 10 (F3)")
    if head.action != action:
        problems.append(f"action {head.action:02x}, expected the request's {action:02x}")
    shape = b"".join(header_field_bytes(raw, f) for f in ("block_type", "block_count", "block_length"))
    if shape != b"\x00\x00\x00\x00":
        problems.append(f"block type/N/L {shape.hex(' ')}, expected 00 00 00 00")
    if len(raw) != 14:
        problems.append(f"{len(raw)} bytes, expected 14")
    return problems


A2_ACTIONS = [
    ("none", [NONE]), ("cycle-on-off", [OFF, ON, OFF]), ("pose", [POSE]), ("register-pose", [REG]),
    ("tolerance", [TOL]), ("malformed-pose", [None]),
]


def malformed_set(action: Action, first: int, profile: Profile) -> list[tuple[str, bytes]]:
    """Three parse errors (B3, B5 length, B5 count) for a 23/24/25 request."""
    pose = action in (POSE, REG)
    btype, blen = (1, 25) if pose else (2, 5)
    block = lambda i: bytes([i]) + bytes(blen - 1)  # noqa: E731
    return [
        ("indexes with a gap", encode_raw(Header(action=action, block_type=btype, block_count=2, block_length=blen),
                                          block(first) + block(first + 2), profile=profile)),
        (f"block length {blen - 1}", encode_raw(Header(action=action, block_type=btype, block_count=1, block_length=blen - 1),
                                                block(first)[:-1], profile=profile)),
        ("no blocks (N=0)", encode_raw(Header(action=action, block_type=btype, block_count=0, block_length=blen),
                                       profile=profile)),
    ]


NOT_REQUESTS: list[tuple[str, dict[str, int], str]] = [
    ("start-fffe", {"start_word": 0xFFFE}, ""),
    ("start-feff", {"start_word": 0xFEFF}, ""),
    ("start-0000-pose", {"start_word": 0x0000}, "pose"),
    ("version-0000", {"version": 0x0000}, ""),
    ("version-0002", {"version": 0x0002}, ""),
    ("version-0100", {"version": 0x0100}, ""),
    ("version-ffff-pose", {"version": 0xFFFF}, "pose"),
    ("transfer-00", {"transfer_type": 0x00}, ""),
    ("transfer-02", {"transfer_type": 0x02}, ""),
    ("transfer-10", {"transfer_type": 0x10}, ""),
    ("transfer-11-pose", {"transfer_type": 0x11}, "pose"),
    ("transfer-ff", {"transfer_type": 0xFF}, ""),
    ("action-03", {"action": 0x03}, ""),
    ("action-04", {"action": 0x04}, ""),
    ("action-10-pose", {"action": 0x10}, "pose"),
    ("action-22", {"action": 0x22}, ""),
    ("action-28", {"action": 0x28}, ""),
    ("action-80", {"action": 0x80}, ""),
    ("action-ff", {"action": 0xFF}, ""),
]


def not_request(fields: dict[str, int], body: str, isight: CaseContext) -> bytes:
    base: dict[str, int] = {"action": ON}
    if body == "pose":
        block = encode(request(POSE, pose_blocks([(1.0, 2.0, 3.0, 4.0, 5.0, 6.0)], isight.profile.first_index)),
                       isight.profile)[12:-2]
        base = {"action": POSE, "block_type": 1, "block_count": 1, "block_length": 25}
        return encode_raw(Header(**{**base, **fields}), block, profile=isight.profile)
    return encode_raw(Header(**{**base, **fields}), profile=isight.profile)


def type03_answer(action: Action, **_: object) -> Expect:
    def seems_e(o: Outcome) -> bool:
        header = o.error.header if isinstance(o, Malformed) else None
        return header is not None and header.action == action and header.block_type == 0x03

    return Expect("a type-03 block answer that does not parse", seems_e)

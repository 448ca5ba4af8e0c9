"""Helpers of the E cases (conformance/cases/extension_e.py): ProgIdx requests and their judging, the pose stream and the result request."""

from __future__ import annotations

import time
from collections.abc import Sequence

from ..harness.client import Answer, Outcome, TcpConnection
from ..protocol import (
    Action,
    Frame,
    ResultCode,
    ValueBlock,
    pose_blocks,
    request,
    value_blocks,
)
from ..protocol.answers import CONFLICT
from .case_context import CaseContext
from .case_judge import answered
from .record import Requirement

#: E2 with ``progidx_conflict = "error-code"``: "409" in the error field, read as the
#: number 409 (0x0199) or written like the document's other codes ("10 01") as 04 09.
CONFLICT_ERRORS = (CONFLICT, 0x0409)

POSE = (800.0, 0.0, 300.0, 180.0, 0.0, 90.0)


def prog_idx(isight: CaseContext, value: int) -> Frame:
    return request(Action.PROG_IDX, value_blocks([value], isight.profile.first_index))


def err(code: int) -> str:
    return f"0x{code:04X}"


def prog_idx_checks(*clauses: str) -> dict[str, Requirement]:
    """E2's requirements for ProgIdx, under the clauses the case judges it with."""
    return {
        "prog-idx": Requirement(clauses, "ProgIdx (26) is answered with one type-03 block (index + int32, L = 5)",
                                accept=answered(Action.PROG_IDX)),
        "prog-idx-block": Requirement(clauses, "ProgIdx is answered with the same index ({value}) or 409 in the "
                                      "block; the error field stays 0000 (profile progidx_conflict=block)"),
        "prog-idx-error-code": Requirement(clauses, "ProgIdx is answered with the same index ({value}) and error "
                                           "0000, or with 409 in the error field (profile progidx_conflict=error-code)"),
    }


def judge_prog_idx(isight: CaseContext, outcome: Outcome, value: int, sent: bytes) -> bool:
    """E2: the answer to ProgIdx(``value``) is one type-03 block with the same index, or 409.

    Honours ``profile.progidx_conflict``: "block" (409 in the block, error 0000) or
    "error-code" (409 in the error field). Returns True when the box reported a conflict.
    """
    isight.judge(outcome, "prog-idx", sent=sent)
    assert isinstance(outcome, Answer)
    frame = outcome.frame
    got = frame.blocks[0].value if frame.blocks and isinstance(frame.blocks[0], ValueBlock) else None
    code = frame.error_code
    mode = isight.profile.progidx_conflict
    isight.details.setdefault("prog_idx_answers", []).append({"sent": value, "value": got, "error": err(code)})
    if mode == "block":
        if code == 0 and got in (value, CONFLICT):
            return got == CONFLICT and value != CONFLICT
        hint = " (the box puts 409 in the error field: rerun with --progidx-conflict=error-code)" \
            if code in CONFLICT_ERRORS else ""
        raise isight.broken("prog-idx-block", expected=f"error 0x0000 and block value {value} or 409",
                            observed=f"error {err(code)} and block value {got}{hint}", sent=sent,
                            received=outcome.raw, value=value)
    if code == 0 and got == value:
        return False
    if code in CONFLICT_ERRORS:
        isight.details["conflict_error_code"] = err(code)
        return True
    hint = " (409 travels in the block: rerun with --progidx-conflict=block)" if code == 0 and got == CONFLICT else ""
    raise isight.broken("prog-idx-error-code",
                        expected=f"error 0x0000 with block value {value}, or error 409 (0x0199 or 0x0409)",
                        observed=f"error {err(code)} and block value {got}{hint}", sent=sent, received=outcome.raw,
                        value=value)


def stream_poses(isight: CaseContext, stream: TcpConnection, poses: Sequence[Sequence[float]], phase: str) -> None:
    """Send poses at the profile's rate, each answered 0000 (S3, S6) within time_out."""
    period = 1.0 / isight.profile.pose_rate_hz
    first = isight.profile.first_index
    for i, pose in enumerate(poses):
        start = time.monotonic()
        frame = request(Action.POSE, pose_blocks([pose], first))
        outcome = stream.request(frame, f"{phase}: pose {i + 1}/{len(poses)}")
        isight.judge(outcome, "pose", sent=stream.codec.encode(frame), phase=phase)
        assert isinstance(outcome, Answer)
        isight.latencies_ms.append(outcome.latency_s * 1000)
        time.sleep(max(0.0, period - (time.monotonic() - start)))


def request_result(isight: CaseContext, conn: TcpConnection) -> int:
    """27 within vision_time_out; 202 (busy) is retried until vision_time_out has passed. Each try waits its
    own vision_time_out (E5 bounds every 27), not what is left of the first one's."""
    vision_s = isight.profile.vision_time_out_ms / 1000
    deadline = time.monotonic() + vision_s
    retry_gap = min(0.2, vision_s / 10)
    tries = 0
    while True:
        tries += 1
        outcome = conn.request(request(Action.VISION_RESULT), f"result request (27), try {tries}", timeout_s=vision_s)
        isight.judge(outcome, "result", sent=isight.transcript.sent(conn.conn_id)[-14:])
        assert isinstance(outcome, Answer)
        value = outcome.frame.blocks[0].value  # type: ignore[union-attr]
        isight.details["result_tries"] = tries
        if value != ResultCode.BUSY:
            return int(value)
        if time.monotonic() + retry_gap >= deadline:
            isight.inform(f"the box stayed busy (202) for vision_time_out ({vision_s * 1000:.0f} ms, {tries} tries)")
            return int(value)
        time.sleep(retry_gap)

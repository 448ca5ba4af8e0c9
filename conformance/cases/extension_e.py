"""E: the optional extension (program index 26, vision result 27, type-03 blocks).

Every case first calls ``isight.require_extension()``: a box without 26/27 SKIPs
them (detected once per session on positive evidence, see
:mod:`conformance.harness.extension_probe`, or forced by ``--extension on|off``). A box whose
answer to 26 or 27 carries a type-03 block counts as implementing E even when the
answer does not parse (e.g. result code 404): the E cases then judge it.

Profile settings honoured: ``progidx_conflict`` (E2: a 409 travels in the block
with error 0000, or in the error field), ``vision_time_out_ms`` (E3, E4) and
``time_out_ms`` (E5); the type-03 block's index follows the first index (B3: the codec applies it).
"""

from __future__ import annotations

import time
from collections.abc import Sequence

import pytest

from conformance.protocol import (
    Action,
    ErrorCode,
    Frame,
    ResultCode,
    ValueBlock,
    request,
)
from conformance.protocol.answers import CONFLICT, Cycle, block_value
from conformance.suite import (
    Answer,
    CaseContext,
    Closed,
    Expect,
    Inconclusive,
    Level,
    Malformed,
    Outcome,
    PrimerTrajectory,
    Requirement,
    Silence,
    TcpConnection,
    answered,
    answered_allowed,
    case,
)

# -- the family's helpers: Helpers of the E cases (conformance/cases/extension_e.py): ProgIdx requests and their judging, the pose stream and the result request.
#: E2 with ``progidx_conflict = "error-code"``: "409" in the error field, read as the
#: number 409 (0x0199) or written like the document's other codes ("10 01") as 04 09.
CONFLICT_ERRORS = (CONFLICT, 0x0409)

POSE = (800.0, 0.0, 300.0, 180.0, 0.0, 90.0)


def prog_idx(isight: CaseContext, value: int) -> Frame:
    return request(Action.PROG_IDX, isight.codec.value_blocks([value]))


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
    for i, pose in enumerate(poses):
        start = time.monotonic()
        frame = request(Action.POSE, isight.codec.pose_blocks([pose]))
        outcome = stream.request(frame, f"{phase}: pose {i + 1}/{len(poses)}")
        isight.judge(outcome, "pose", sent=stream.codec.encode(frame), phase=phase)
        assert isinstance(outcome, Answer)
        isight.latencies_ms.append(outcome.latency_s * 1000)
        time.sleep(max(0.0, period - (time.monotonic() - start)))


def request_result(isight: CaseContext, conn: TcpConnection) -> int:
    """27 within vision_time_out; 202 (busy) is retried until vision_time_out has passed. Each try waits its
    own vision_time_out (E5 bounds every 27), not what is left of the first one's."""
    vision_s = isight.profile.vision_time_out_s
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


# -- the cases

# -- E1 ------------------------------------------------------------------------------------


@pytest.mark.parametrize("value", [-1, -(2**31), 2**31 - 1, 0x01020304], ids=["negative", "int32-min", "int32-max", "bytes"])
@case("E1-01", ["E1", "E2"], Level.MUST, "A ProgIdx block holds any signed big-endian int32",
      "a ProgIdx with a negative or large int32 is well-formed: answered with one type-03 block holding the "
      "same value (or 409 per the profile's progidx_conflict)", checks=prog_idx_checks("E1", "E2"))
def test_prog_idx_int32_range(isight: CaseContext, value: int) -> None:
    isight.require_extension()
    frame = prog_idx(isight, value)
    outcome = isight.exchange(frame, f"ProgIdx with int32 {value} ({value & 0xFFFFFFFF:08x})")
    if judge_prog_idx(isight, outcome, value, isight.last_sent):
        isight.inform(f"the box answered ProgIdx {value} with 409 (conflict); the int32 echo was not seen")


# -- E2 ------------------------------------------------------------------------------------


@case("E2-01", ["E2", "E1"], Level.MUST, "ProgIdx is answered with the same index or 409",
      "one type-03 block holding the index sent, or 409 (in the block with error 0000, or in the error "
      "field when the profile's progidx_conflict is error-code)", checks=prog_idx_checks("E2"))
def test_prog_idx_answer(isight: CaseContext) -> None:
    isight.require_extension()
    outcome = isight.exchange(prog_idx(isight, 7), "ProgIdx: program index 7")
    if judge_prog_idx(isight, outcome, 7, isight.last_sent):
        isight.inform("the box answered ProgIdx with 409 (resource conflict / not ready)")


# -- E3 ------------------------------------------------------------------------------------


@case("E3-01", ["E3", "E1"], Level.MUST, "A result request is answered with a ResultCode within vision_time_out",
      "one type-03 block holding 1, 2, 10, 20, 202, 400 or 409 (never 0 or 404), within vision_time_out",
      checks={"": Requirement(("E3",), "a result request is answered within vision_time_out ({vision_ms:.0f} ms) with one "
                              "type-03 block holding a ResultCode the box may send (1, 2, 10, 20, 202, 400, 409; "
                              "never 0 or 404)", accept=answered_allowed(Action.VISION_RESULT, request=request(Action.VISION_RESULT)))})
def test_vision_result(isight: CaseContext) -> None:
    isight.require_extension()
    vision_s = isight.profile.vision_time_out_s
    conn = isight.connect()
    frame = request(Action.VISION_RESULT)
    outcome = conn.request(frame, "result request (27)", timeout_s=vision_s)
    isight.judge(outcome, sent=isight.transcript.sent(conn.conn_id), vision_ms=vision_s * 1000)
    assert isinstance(outcome, Answer)
    isight.latencies_ms.append(outcome.latency_s * 1000)
    isight.details["result_code"] = outcome.frame.blocks[0].value  # type: ignore[union-attr]
    isight.details["error_code"] = err(outcome.frame.error_code)



@case("E3-02", ["E3", "E1"], Level.MUST, "The run's first result request, before any cycle, gets a ResultCode",
      "the result request sent at session start (before the suite ran any cycle: the robot asking for a result "
      "after a restart) is answered with one type-03 block holding 1, 2, 10, 20, 202, 400 or 409, never 0 or 404",
      checks={"": Requirement(("E3",), "the first result request of the run, before any cycle, is answered with one "
                              "type-03 block holding a ResultCode the box may send (1, 2, 10, 20, 202, 400, 409; "
                              "never 0, the robot's empty initial value, or 404)",
                              accept=answered_allowed(Action.VISION_RESULT, request=request(Action.VISION_RESULT)))})
def test_first_result_before_any_cycle(isight: CaseContext) -> None:
    isight.require_extension()
    first = isight.session.first_result
    if first is None or first.unanswered or not isinstance(first.outcome, (Answer, Malformed)):
        raise Inconclusive("the session's first result request got no answer to judge (E3-01 judges whether 27 is "
                           "answered at all)" if first is not None else
                           "no result request went out at session start (the box did not answer it, or --extension "
                           "off)")
    isight.details["sent"] = ("at session start, before any case's CycleOn: its bytes are in the pcap of the run's "
                              "first case (T1-00)")
    code = block_value(first.outcome.raw, isight.profile.byte_order)
    if code is not None:
        isight.details["result_code"] = code  # kept for the root cause, whatever the verdict
    isight.judge(first.outcome, sent=isight.codec.encode(request(Action.VISION_RESULT)))


# -- E4 ------------------------------------------------------------------------------------


@case("E4-01", ["E4", "E2", "E3", "S1"], Level.MUST, "The extended canonical session completes",
      "ProgIdx → stream on → CycleOn → trajectory → CycleOff → stream off → 1 s → result request: ProgIdx "
      "echoed, every other answer 0000, a ResultCode within vision_time_out (202 retried; still busy is "
      "INFORMATIONAL; ProgIdx 409, CycleOn 0001 or CycleOff 0002 make the rest INCONCLUSIVE)",
      checks={**prog_idx_checks("E4", "E2"),
              "pose": Requirement(("E4", "S3"), "every pose of the stream is answered 0000 ({phase})",
                                  accept=answered_allowed(Action.POSE)),
              "on": Requirement(("E4", "S2"), "CycleOn is answered 0000 (or 0001)", accept=answered_allowed(Action.CYCLE_ON, Cycle.IDLE),
                                inconclusive=answered(Action.CYCLE_ON, [ErrorCode.NOT_READY]),
                                inconclusive_text="CycleOn answered 0001 (box not ready): the rest of the session is "
                                                  "not judged (S2)"),
              "off": Requirement(("E4", "S1"), "CycleOff is answered 0000", accept=answered_allowed(Action.CYCLE_OFF, Cycle.ON),
                                 inconclusive=answered(Action.CYCLE_OFF, [ErrorCode.CYCLE_OFF_FAILED]),
                                 inconclusive_text="CycleOff answered 0002 (detection not closed): the result is not "
                                                   "judged (A3)"),
              "result": Requirement(("E4", "E3"), "the result request is answered within vision_time_out with a ResultCode "
                                    "(1, 2, 10, 20, 202, 400, 409)",
                                    accept=answered_allowed(Action.VISION_RESULT, request=request(Action.VISION_RESULT)))})
def test_extended_session(isight: CaseContext) -> None:
    isight.require_extension()
    conn = isight.connect("command")
    outcome = conn.request(prog_idx(isight, 3), "ProgIdx: program index 3")
    if judge_prog_idx(isight, outcome, 3, isight.transcript.sent(conn.conn_id)):
        raise Inconclusive("ProgIdx answered 409 (conflict / not ready): the session cannot go on (E2)")
    stream = isight.connect("stream", target=isight.session.stream_target())
    path = PrimerTrajectory(duration=0.3)
    rate = isight.profile.pose_rate_hz
    samples = [pose for _, pose in path.samples(rate)]
    stream_poses(isight, stream, [path.home] * 3, "stream on, before CycleOn")
    isight.judge(conn.request(request(Action.CYCLE_ON), "CycleOn"), "on", sent=b"")
    stream_poses(isight, stream, samples, "trajectory")
    isight.judge(conn.request(request(Action.CYCLE_OFF), "CycleOff"), "off", sent=b"")
    stream.close("Send_Pos_Off")
    time.sleep(1.0)  # E4: the robot waits 1 s before it asks for the result
    isight.details["result_code"] = request_result(isight, conn)
    conn.close()


# -- E5 ------------------------------------------------------------------------------------


@case("E5-01", ["E5", "T1"], Level.MUST, "time_out bounds every action except 27",
      "ProgIdx and every core action (00, 01, 23, 24, 25, 02) are answered within time_out",
      checks={"": Requirement(("E5", "T1"), "time_out ({time_out_ms:.0f} ms) bounds {name}: it is answered within time_out",
                              accept=Expect("an answer within time_out",
                                            lambda o: not isinstance(o, (Silence, Closed))))})
def test_time_out_bounds_actions(isight: CaseContext) -> None:
    isight.require_extension()
    steps: list[tuple[str, Frame]] = [
        ("NONE", request(Action.NONE)),
        ("PROG_IDX", prog_idx(isight, 1)),
        ("CYCLE_ON", request(Action.CYCLE_ON)),
        ("POSE", request(Action.POSE, isight.codec.pose_blocks([POSE]))),
        ("REGISTER_POSE", request(Action.REGISTER_POSE, isight.codec.pose_blocks([POSE]))),
        ("TOLERANCE", request(Action.TOLERANCE, isight.codec.tolerance_blocks([0.5]))),
        ("CYCLE_OFF", request(Action.CYCLE_OFF)),
    ]
    conn = isight.connect()
    latencies: dict[str, float] = {}
    for name, frame in steps:
        outcome = conn.request(frame, f"{name} request (E5: bounded by time_out)")
        isight.judge(outcome, sent=conn.codec.encode(frame), name=name, time_out_ms=isight.time_out_s * 1000)
        assert isinstance(outcome, (Answer, Malformed))
        latency = outcome.latency_s
        latencies[name] = round(latency * 1000, 3)
        isight.latencies_ms.append(latency * 1000)
    isight.details["latency_ms"] = latencies

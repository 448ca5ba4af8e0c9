"""Helpers of the S cases (conformance/cases/session_rules.py): the session's requirements, asking and cycling, the stream, latency comparisons."""

from __future__ import annotations

import time

from ..harness.client import Answer, TcpConnection
from ..protocol import Action, ErrorCode, Frame, pose_blocks, request, tolerance_blocks
from ..protocol.answers import Cycle
from .case_context import CaseContext
from .case_judge import answered, answered_allowed
from .record import Requirement
from .sequence import percentile

HOME = (800.0, -100.0, 300.0, 180.0, 0.0, 0.0)

ON, OFF, NONE, POSE = Action.CYCLE_ON, Action.CYCLE_OFF, Action.NONE, Action.POSE

NONE_0 = Requirement(("A1",), "NONE is answered 0000", accept=answered_allowed(NONE))

CYCLE_ON = Requirement(("S2",), "CycleOn is answered 0000, or 0001 when not ready", accept=answered_allowed(ON, Cycle.IDLE))

READY = Requirement(("S2",), "the box is ready for a cycle", inconclusive=answered(ON, [ErrorCode.NOT_READY]),
                    inconclusive_text="CycleOn answered 0001 (box not ready): the rest of the cycle cannot be judged (S2)")

POSES_0 = Requirement(("S3",), "poses are answered 0000 whether or not a cycle is on", accept=answered_allowed(POSE))


def step_frame(isight: CaseContext, action: Action) -> Frame:
    first = isight.profile.first_index
    if action in (Action.POSE, Action.REGISTER_POSE):
        return request(action, pose_blocks([HOME], first))
    if action is Action.TOLERANCE:
        return request(action, tolerance_blocks([0.5], first))
    return request(action)


def ask(isight: CaseContext, conn: TcpConnection, action: Action, check: str = "answered") -> Answer:
    """One request on ``conn``, judged by the case's requirement ``check``; latency recorded."""
    frame = step_frame(isight, action)
    sent = conn.codec.encode(frame)
    outcome = conn.request(sent, f"{action.name} request")
    if isinstance(outcome, Answer):
        isight.latencies_ms.append(outcome.latency_s * 1000)
    isight.judge(outcome, check, sent=sent, action=action)
    assert isinstance(outcome, Answer)
    return outcome


def cycle_on(isight: CaseContext, conn: TcpConnection) -> None:
    """CycleOn: 0000, or 0001 (box not ready) which makes the rest INCONCLUSIVE (S2), after a CycleOff."""
    outcome = ask(isight, conn, ON, "cycle-on")
    if outcome.frame.error_code == 1:
        ask(isight, conn, OFF)  # leave the box idle
    isight.judge(outcome, "ready")


def open_stream(isight: CaseContext, label: str = "stream") -> TcpConnection:
    return isight.connect(label, target=isight.session.stream_target())


def p50_latency(isight: CaseContext, conn: TcpConnection, count: int, check: str, gap_s: float = 0.0) -> list[float]:
    out = []
    for _ in range(count):
        out.append(ask(isight, conn, NONE, check).latency_s * 1000)
        if gap_s:
            time.sleep(gap_s)
    return out


def not_delayed(isight: CaseContext, base: list[float], during: list[float]) -> None:
    b, d = percentile(base, 50), percentile(during, 50)
    limit = b + max(100.0, 5 * b)
    if d > limit:
        raise isight.broken(expected=f"command p50 ≤ {limit:.1f} ms (baseline p50 {b:.1f} ms + max(100 ms, 5×))",
                            observed=f"command p50 {d:.1f} ms (max {max(during):.1f} ms)")

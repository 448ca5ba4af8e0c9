"""Helpers of the R2-R6 cases (conformance/cases/robustness.py): garbage, held connections, the whole frame as a reference, resynchronisation."""

from __future__ import annotations

import random
import time

from ..harness.client import Answer, Closed, TcpConnection
from ..protocol import Action, Frame, pose_blocks, request, tolerance_blocks
from ..protocol.constants import START_BYTES
from .case_context import CaseContext
from .case_judge import CLOSED, answered, answered_allowed
from .record import Expect, Requirement
from .requirements import NOT_ANSWERED
from .sequence import DEFAULT_POSE

#: R2: a fresh connection after the input gets NONE answered 0000
ALIVE = Requirement(("R2",), "whatever bytes one connection sends, the box keeps accepting and answering new connections "
                    "(after {after})", accept=answered_allowed(Action.NONE))


def valid_frames(isight: CaseContext) -> dict[str, Frame]:
    first = isight.profile.first_index
    return {
        "none": request(Action.NONE),
        "pose": request(Action.POSE, pose_blocks([DEFAULT_POSE], first)),
        "tolerance": request(Action.TOLERANCE, tolerance_blocks([1.5, 2.5], first)),
        "register-pose": request(Action.REGISTER_POSE, pose_blocks([DEFAULT_POSE, (1, 2, 3, 4, 5, 6)], first)),
    }


def assert_alive(isight: CaseContext, after: str) -> None:
    isight.judge(isight.check_alive(), "alive", after=after)


def no_fe(data: bytes) -> bytes:
    return data.replace(b"\xfe", b"\x00")


GARBAGE = {
    "random-bytes": no_fe(random.Random(2024).randbytes(4096)),
    "64k-of-fe": b"\xfe" * 65536,
}

#: R3: the reference answer to the whole frame, to compare a split delivery with
WHOLE = Requirement(("R3",), "the whole {frame.action.name} request is answered, as a reference", inconclusive=NOT_ANSWERED,
                    inconclusive_text="the whole {frame.action.name} request was not answered: nothing to compare the "
                                      "split delivery with")

#: R3: a split delivery is answered like the whole frame
LIKE_WHOLE = lambda action, code, **_: answered(action, [code])  # noqa: E731


def like_whole(isight: CaseContext, frame: Frame) -> Answer:
    outcome = isight.exchange(frame, f"{frame.action.name} request, whole (reference)")
    isight.judge(outcome, "whole", frame=frame)
    assert isinstance(outcome, Answer)
    return outcome


def hold_connections(isight: CaseContext, label: str, count: int, data: bytes, deadline: float) -> list[TcpConnection]:
    """Open up to ``count`` connections (each sends ``data``); stop at the first refusal or the deadline."""
    out = []
    for i in range(count):
        left = deadline - time.monotonic()
        if left <= 0:
            break
        conn = isight.try_connect(f"{label} {i + 1}", time_out_s=min(isight.time_out_s, left))
        if conn is None:
            break
        if data:
            conn.send(data, f"{label}: {len(data)} bytes, then nothing")
        out.append(conn)
    return out


def fresh_answered(isight: CaseContext, when: str) -> None:
    """A fresh connection gets NONE and a pose answered 0000 within time_out. A box may make room by
    evicting a stale connection: a fresh connection it resets is retried until time_out has passed."""
    deadline = time.monotonic() + isight.time_out_s
    attempts = 0
    while True:
        attempts += 1
        left = deadline - time.monotonic()
        conn = isight.try_connect(f"fresh ({when}, attempt {attempts})", time_out_s=max(0.05, left))
        if conn is None:
            raise isight.broken(expected="a fresh connection is accepted within time_out",
                                observed=f"connection attempt {attempts} was not accepted", when=when)
        outcome = conn.request(request(Action.NONE), f"NONE on a fresh connection ({when})", timeout_s=max(0.05, left))
        if isinstance(outcome, Closed) and time.monotonic() + 0.1 < deadline:
            conn.close()
            time.sleep(0.1)
            continue
        break
    isight.details.setdefault("fresh_attempts", {})[when] = attempts
    for frame in (None, valid_frames(isight)["pose"]):
        if frame is not None:
            outcome = conn.request(frame, f"POSE on a fresh connection ({when})")
        action = Action.NONE if frame is None else frame.action
        if isinstance(outcome, Answer):
            isight.latencies_ms.append(outcome.latency_s * 1000)
        isight.judge(outcome, sent=conn.codec.encode(frame or request(Action.NONE)), action=action, when=when)
    conn.close()


RESYNC_GARBAGE = {
    "ascii": b"hello iSight\r\n",
    "zeros": b"\x00" * 32,
    "bad-start-word": b"\xfe\xff\x00\x01\x01\x00\x00\x00\x00\x00\x00\x00\x00\x00",
    "bad-version": START_BYTES + b"\x00\x02\x01\x00\x00\x00\x00\x00\x00\x00\x00\x00",
}


def resynced(action: Action, **_: object) -> Expect:
    return answered_allowed(action) | CLOSED

"""T: timing (every answer within time_out; the pose stream at its rate without backlog)."""

from __future__ import annotations

import time

from conformance.protocol import Action, Frame, encode, request
from conformance.suite import (
    DEFAULT_POSE,
    Answer,
    CaseContext,
    Level,
    Outcome,
    PoseStream,
    Requirement,
    answered,
    case,
    latency_figures,
)


# -- the family's helpers: Helpers of the T cases (conformance/cases/time_limits.py): the requests timed and the time_out check.
def timed_requests(isight: CaseContext) -> list[Frame]:
    pose = request(Action.POSE, isight.codec.pose_blocks([DEFAULT_POSE]))
    return [
        request(Action.NONE),
        request(Action.TOLERANCE, isight.codec.tolerance_blocks([0.5])),
        request(Action.REGISTER_POSE, isight.codec.pose_blocks([DEFAULT_POSE])),
        request(Action.CYCLE_ON),
        *[pose] * 20,
        request(Action.CYCLE_OFF),
        request(Action.POSE, isight.codec.pose_blocks([DEFAULT_POSE] * 255)),  # the largest legal frame
    ]


def judge_within_time_out(isight: CaseContext, outcome: Outcome, frame: Frame, where: str) -> None:
    if isinstance(outcome, Answer):
        isight.latencies_ms.append(outcome.latency_s * 1000)
    isight.judge(outcome, sent=encode(frame, isight.profile), action=frame.action, where=where,
                 time_out_ms=isight.time_out_s * 1000)


# -- the cases

@case("T1-01", ["T1", "A1"], Level.MUST, "Every answer arrives within time_out",
      "each request of a session (NONE, Tolerance, RegisterPose, CycleOn, 20 poses, CycleOff, a 255-pose frame) "
      "and five requests on fresh connections are answered within time_out; latency distribution reported",
      checks={"": Requirement(("T1",), "every answer arrives within time_out ({time_out_ms:.0f} ms) of its request ({where})",
                              accept=lambda action, **_: answered(action))})
def test_every_answer_within_time_out(isight: CaseContext) -> None:
    conn = isight.connect()
    for i, frame in enumerate(timed_requests(isight)):
        outcome = conn.request(frame, f"{frame.action.name} request")
        judge_within_time_out(isight, outcome, frame, f"request {i + 1} on one connection")
    conn.close()
    connects = []
    for i in range(5):
        start = time.monotonic()
        fresh = isight.connect("fresh")
        connects.append((time.monotonic() - start) * 1000)
        frame = request(Action.NONE)
        judge_within_time_out(isight, fresh.request(frame, "NONE request"), frame, f"fresh connection {i + 1}")
        fresh.close()
    isight.details.update(latency=latency_figures(isight.latencies_ms), connect=latency_figures(connects),
                          time_out_ms=isight.profile.time_out_ms)


@case("T2-01", ["T2", "S6", "T1"], Level.MUST, "The pose stream at the profile rate: every pose answered, no backlog",
      "streaming at the profile rate for --stream-seconds, every pose answered 0000 within time_out, none lost, "
      "and last-quarter p50 latency ≤ first-quarter p50 + max(20 ms, first-quarter p50)",
      checks={"stream": Requirement(("T2",), "at the configured stream rate")})
def test_stream_at_rate(isight: CaseContext) -> None:
    rate, seconds = isight.profile.pose_rate_hz, isight.settings.stream_seconds
    conn = isight.connect("stream", target=isight.session.stream_target())
    result = PoseStream(conn, rate, seconds, isight.time_out_s).start().wait()
    isight.latencies_ms.extend(result.latencies_ms)
    isight.details["stream"] = result.figures()
    if result.max_send_lag_ms > max(2000 / rate, 10.0):
        isight.details["note"] = (f"the suite's sender fell {result.max_send_lag_ms:.0f} ms behind its schedule "
                                  "(a loaded test machine): poses were sent in catch-up bursts")
    isight.judge_stream(result, backlog=True)
    conn.close("Send_Pos_Off")

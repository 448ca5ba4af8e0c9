"""Helpers of the T cases (conformance/cases/time_limits.py): the requests timed and the time_out check."""

from __future__ import annotations

from ..harness.client import Answer, Outcome
from ..protocol import Action, Frame, encode, pose_blocks, request, tolerance_blocks
from .case_context import CaseContext
from .sequence import DEFAULT_POSE


def timed_requests(isight: CaseContext) -> list[Frame]:
    first = isight.profile.first_index
    pose = request(Action.POSE, pose_blocks([DEFAULT_POSE], first))
    return [
        request(Action.NONE),
        request(Action.TOLERANCE, tolerance_blocks([0.5], first)),
        request(Action.REGISTER_POSE, pose_blocks([DEFAULT_POSE], first)),
        request(Action.CYCLE_ON),
        *[pose] * 20,
        request(Action.CYCLE_OFF),
        request(Action.POSE, pose_blocks([DEFAULT_POSE] * 255, first)),  # the largest legal frame
    ]


def judge_within_time_out(isight: CaseContext, outcome: Outcome, frame: Frame, where: str) -> None:
    if isinstance(outcome, Answer):
        isight.latencies_ms.append(outcome.latency_s * 1000)
    isight.judge(outcome, sent=encode(frame, isight.profile), action=frame.action, where=where,
                 time_out_ms=isight.time_out_s * 1000)

"""Helpers of the F cases (conformance/cases/frame.py): the pose request and an answer's bytes."""

from __future__ import annotations

from ..harness.client import Answer
from ..protocol import Action, pose_blocks, request
from .case_context import CaseContext

POSE = request(Action.POSE, pose_blocks([(500.0, 0.0, 300.0, 180.0, 0.0, 90.0)]))


def answer_bytes(isight: CaseContext, action: Action = Action.NONE) -> tuple[Answer, bytes]:
    outcome = isight.exchange(request(action), f"{action.name} request")
    isight.judge(outcome, "answered", sent=b"", action=action)
    assert isinstance(outcome, Answer)
    return outcome, outcome.raw

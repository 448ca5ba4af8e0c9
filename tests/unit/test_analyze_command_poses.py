"""Poses on the command connection (ISIGHT(3,35) / (3,36), row robot-command-poses of the legal table):
the passive judges see their answers, so a robot that awaits them is clean and one that does not is not.

Issue 26: a pose sent on the command connection after CycleOn was both the connection's first
pose and its first pose in the cycle; the session kept it twice and judged it against itself
("0.0 ms after POSE (frame 43) and before its answer"), and it kept no answer for it.
"""

from __future__ import annotations

from pathlib import Path

from conformance.analyze import AnalyzeConfig, analyze, build_cases
from conformance.model.verdicts import Verdict
from conformance.protocol import Action, answer, encode, pose_blocks, request
from tests.analyze_util import POSE, POSE_OK, Capture, exchange

LOOSE = AnalyzeConfig(rate_tolerance=0.5, jitter_tolerance=3.0)
REGISTER = encode(request(Action.REGISTER_POSE, pose_blocks([(1.0, 2.0, 3.0, 0.0, 0.0, 0.0)])))
REGISTER_OK = encode(answer(Action.REGISTER_POSE))


def _session(cap: Capture, cmd_requests: list[tuple[bytes, bytes | None]], at: str, await_answers: bool = True,
             poses: int = 30) -> None:
    """S1 with ``cmd_requests`` written on the command connection ``at`` "start" (before CycleOn) or
    "cycle" (between CycleOn and CycleOff); ``await_answers=False``: the robot sends CycleOff before the
    last of them is answered."""
    cmd, stream = cap.tcp(41000), cap.tcp(41001)
    for i in range(poses):
        stream.robot(POSE, t=cap.t + 0.02)
        stream.box(POSE_OK, t=cap.t + 0.0004)
        if i == 0 and at == "start":
            for req, ans in cmd_requests:
                exchange(cmd, req, ans)
        if i == 1:
            exchange(cmd, encode(request(Action.CYCLE_ON)), encode(answer(Action.CYCLE_ON)))
        if i == 5 and at == "cycle":
            for req, ans in cmd_requests[:-1]:
                exchange(cmd, req, ans)
            req, ans = cmd_requests[-1]
            cmd.robot(req)
            if await_answers:
                cmd.box(ans or b"")
        if i == poses - 2:
            cmd.robot(encode(request(Action.CYCLE_OFF)))
            if not await_answers:
                cmd.box(cmd_requests[-1][1] or b"")
            cmd.box(encode(answer(Action.CYCLE_OFF)))
    stream.close()
    cmd.close()


def _cases(cap: Capture, tmp_path: Path) -> dict:
    return {c.id: c for c in build_cases(analyze(cap.write(tmp_path / "s.pcapng"), LOOSE))}


def test_a_pose_on_the_command_connection_during_the_cycle_is_clean(tmp_path: Path) -> None:
    cap = Capture()
    _session(cap, [(POSE, POSE_OK)], "cycle")
    c = _cases(cap, tmp_path)
    assert c["OBS-A1-robot"].verdict is Verdict.PASS, c["OBS-A1-robot"].message
    assert c["OBS-S1-robot"].verdict is Verdict.PASS, c["OBS-S1-robot"].message
    assert c["OBS-A1-box"].verdict is Verdict.PASS


def test_a_pose_and_a_register_pose_before_the_cycle_are_clean(tmp_path: Path) -> None:
    cap = Capture()
    _session(cap, [(POSE, POSE_OK), (REGISTER, REGISTER_OK)], "start")
    c = _cases(cap, tmp_path)
    assert c["OBS-A1-robot"].verdict is Verdict.PASS, c["OBS-A1-robot"].message
    assert c["OBS-S1-robot"].verdict is Verdict.PASS, c["OBS-S1-robot"].message


def test_poses_of_both_kinds_during_the_cycle_are_clean(tmp_path: Path) -> None:
    cap = Capture()
    _session(cap, [(encode(request(Action.NONE)), encode(answer(Action.NONE))), (POSE, POSE_OK),
                   (REGISTER, REGISTER_OK)], "cycle")
    c = _cases(cap, tmp_path)
    assert c["OBS-A1-robot"].verdict is Verdict.PASS, c["OBS-A1-robot"].message


def test_a_robot_that_does_not_await_its_command_pose_still_fails_a1(tmp_path: Path) -> None:
    cap = Capture()
    _session(cap, [(POSE, POSE_OK)], "cycle", await_answers=False)
    c = _cases(cap, tmp_path)
    a1 = c["OBS-A1-robot"]
    assert a1.verdict is Verdict.FAIL
    assert "CYCLE_OFF" in a1.message and "after POSE" in a1.message and "its answer went out" in a1.message
    assert "0.0 ms after" not in a1.message

"""The robot's session as data, sans-I/O: the step table, the session's order, and the judges that
read each answer (no sockets, no clocks: the driver is tested in test_robot.py)."""

import ast
from pathlib import Path

import pytest

from conformance.endpoints.robot import robot_result, robot_steps
from conformance.endpoints.robot.robot_result import EXIT_MISBEHAVED, EXIT_NOT_READY, EXIT_OK, RobotResult
from conformance.endpoints.robot.robot_steps import (
    E4_STEPS,
    PASS,
    S1_STEPS,
    STEP_TABLE,
    STEPS,
    Io,
    answer_value,
    judge_answer,
    judge_malformed,
    judge_pose,
    session_steps,
)
from conformance.protocol import Action, ErrorCode, ProtocolError, ResultCode, answer, value_blocks
from conformance.protocol.answers import SENDABLE_RESULTS


def judge(step: str, frame, program_index: int = 7):
    judge = STEP_TABLE[step].judge
    assert judge is not None, step
    return judge(frame, program_index)


def test_every_step_of_the_canonical_sessions_is_in_the_table():
    assert set(S1_STEPS) <= STEPS and set(E4_STEPS) <= STEPS and STEPS == set(STEP_TABLE)
    for steps in (S1_STEPS, E4_STEPS):
        assert steps[0] == "connect" and steps[-1] == "disconnect"
    assert [s for s in E4_STEPS if s not in S1_STEPS] == ["prog_idx", "result_wait", "vision_result"]


def test_command_steps_name_their_request_and_judge_and_the_others_do_not():
    for name, step in STEP_TABLE.items():
        assert step.does, name
        if step.io is Io.COMMAND:
            assert step.action is not None and step.judge is not None and step.expects, name
        else:
            assert step.action is None and step.judge is None and step.keep is None, name
    assert [n for n, s in STEP_TABLE.items() if s.carries_index] == ["prog_idx"]
    assert [n for n, s in STEP_TABLE.items() if s.bound == "vision_time_out"] == ["vision_result"]
    assert {n: s.cycle for n, s in STEP_TABLE.items() if s.cycle} == {"cycle_on": "start", "cycle_off": "end"}


def test_the_table_has_no_io():
    """Sans-I/O: the step table and the result import no sockets, loops or clocks."""
    for module in (robot_steps, robot_result):
        tree = ast.parse(Path(module.__file__).read_text(encoding="utf-8"))
        names = {a.name for n in ast.walk(tree) if isinstance(n, ast.Import) for a in n.names}
        names |= {n.module or "" for n in ast.walk(tree) if isinstance(n, ast.ImportFrom)}
        assert not names & {"asyncio", "socket", "time", "selectors", "threading"}, module.__name__


def test_session_steps():
    assert session_steps() == S1_STEPS
    assert session_steps(extension=True) == E4_STEPS
    assert session_steps(ping=True) == ("connect", "ping", *S1_STEPS[1:])
    assert session_steps(ping=True, steps=["connect", "disconnect"]) == ("connect", "disconnect")
    with pytest.raises(ValueError, match="unknown session steps: warp; known: connect, cycle_off"):
        session_steps(steps=["connect", "warp"])


def test_cycle_on_0001_is_a_fatal_not_ready_and_other_codes_break_s1():
    assert judge("cycle_on", answer(Action.CYCLE_ON)) == PASS
    not_ready = judge("cycle_on", answer(Action.CYCLE_ON, ErrorCode.NOT_READY))
    assert (not_ready.code, not_ready.fatal) == (EXIT_NOT_READY, True) and "S2" in not_ready.reason
    wrong = judge("cycle_on", answer(Action.CYCLE_ON, ErrorCode.POSE_ERROR))
    assert (wrong.code, wrong.fatal) == (EXIT_MISBEHAVED, False)
    assert wrong.reason == "CYCLE_ON answered 0x1001 where 0000 expected (S1)"


@pytest.mark.parametrize("step,action,clause", [("cycle_off", Action.CYCLE_OFF, "S1"), ("ping", Action.NONE, "A4")])
def test_0000_steps(step, action, clause):
    assert judge(step, answer(action)) == PASS
    failed = judge(step, answer(action, ErrorCode.CYCLE_OFF_FAILED))
    assert failed.code == EXIT_MISBEHAVED and failed.reason.endswith(f"({clause})") and not failed.fatal


def test_prog_idx_expects_its_index_back_or_409():
    assert judge("prog_idx", answer(Action.PROG_IDX, 0, value_blocks([7]))) == PASS
    ignored = judge("prog_idx", answer(Action.PROG_IDX, 5, value_blocks([7])))
    assert ignored.code == EXIT_OK and ignored.reason == "error field 0x0005 ignored (E2: it stays 0000)"
    conflict = judge("prog_idx", answer(Action.PROG_IDX, 0, value_blocks([ResultCode.CONFLICT])))
    assert (conflict.code, conflict.fatal) == (EXIT_NOT_READY, True)
    other = judge("prog_idx", answer(Action.PROG_IDX, 0, value_blocks([8])))
    assert other.code == EXIT_MISBEHAVED and other.reason == "ProgIdx 7 answered with value 8, expected 7 or 409 (E2)"


def test_vision_result_codes():
    for code in SENDABLE_RESULTS:
        assert judge("vision_result", answer(Action.VISION_RESULT, 0, value_blocks([code]))) == PASS
    for robot_only in (ResultCode.EMPTY, ResultCode.NO_ANSWER):
        assert judge("vision_result", answer(Action.VISION_RESULT, 0, value_blocks([robot_only]))).code == EXIT_MISBEHAVED
    unlisted = judge("vision_result", answer(Action.VISION_RESULT, 0, value_blocks([12345])))
    assert unlisted.code == EXIT_OK and "unlisted ResultCode 12345" in unlisted.reason


def test_keep_records_the_answers_value():
    result = RobotResult()
    frame = answer(Action.VISION_RESULT, 0, value_blocks([202]))
    keep = STEP_TABLE["vision_result"].keep
    assert keep is not None
    keep(result, answer_value(frame))
    assert result.vision_result == 202 and result.prog_idx_answer is None
    assert answer_value(answer(Action.CYCLE_ON)) is None


def test_answers_echo_their_action_and_poses_are_0000():
    assert judge_answer(Action.CYCLE_ON, answer(Action.CYCLE_ON)) == PASS
    echo = judge_answer(Action.CYCLE_ON, answer(Action.CYCLE_OFF))
    assert echo.code == EXIT_MISBEHAVED and "A2" in echo.reason
    assert judge_pose(3, answer(Action.POSE)) == PASS
    assert judge_pose(3, answer(Action.NONE)).reason == "pose #3 answered with action NONE (A2)"
    assert judge_pose(3, answer(Action.POSE, ErrorCode.POSE_ERROR)).reason.endswith("where 0000 expected (S3)")
    bad = judge_malformed("pose #3", ProtocolError("bad start word", clause="F1"))
    assert bad.code == EXIT_MISBEHAVED and bad.reason == "malformed answer to pose #3: [F1] bad start word (at offset 0)"

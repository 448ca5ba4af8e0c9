"""The robot simulator against the reference box (in-process, loopback) and against broken boxes."""

import contextlib
import socket
import socketserver
import struct
import threading

import pytest

from conformance.commands import main
from conformance.endpoints.behaviour import BoxConfig
from conformance.endpoints.loop import BoxThread
from conformance.endpoints.robot import RobotSession, parse_target, run_robot
from conformance.endpoints.robot.robot_result import (
    EXIT_CONNECTION,
    EXIT_MISBEHAVED,
    EXIT_NOT_READY,
    EXIT_OK,
    EXIT_TIMEOUT,
    RobotResult,
)
from conformance.endpoints.robot.robot_steps import E4_STEPS, S1_STEPS, RobotFaults
from conformance.protocol import (
    DEFAULT_PROFILE,
    Action,
    Frame,
    Profile,
    StreamDecoder,
    TransferType,
    answer,
    encode,
    value_blocks,
)

pytestmark = pytest.mark.timeout(60)

FAST = Profile(time_out_ms=5000, vision_time_out_ms=5000)  # generous: a busy CI machine must not time out


def play(address, profile=FAST, **kwargs) -> RobotResult:
    kwargs.setdefault("duration", 0.3)
    kwargs.setdefault("result_wait", 0.1)
    return run_robot(RobotSession(address, profile, **kwargs))


@pytest.fixture(scope="module")
def box():
    with BoxThread(BoxConfig(), udp=False) as b:
        yield b


def commands(result: RobotResult) -> list[str]:
    return [e.text for e in sorted(result.timeline, key=lambda e: e.t_ms) if e.conn == "cmd" and e.text.startswith("->")]


# -- canonical sessions ------------------------------------------------------------------------------------


def test_s1_canonical_session(box):
    result = play(box.address, duration=0.5)
    assert result.ok, result.reason
    assert result.exit_code == EXIT_OK and result.steps == S1_STEPS
    assert commands(result) == ["-> CYCLE_ON", "-> CYCLE_OFF"]
    assert result.poses_sent >= 20 and result.poses_answered == result.poses_sent
    assert len(result.pose_latencies_ms) == result.poses_sent
    assert all(e.answer == "POSE 0000" for e in result.timeline if e.text.startswith("-> POSE"))
    # S1 order: the stream flows before CycleOn and closes after CycleOff
    order = sorted(result.timeline, key=lambda e: e.t_ms)
    first_pose = next(i for i, e in enumerate(order) if e.text.startswith("-> POSE"))
    cycle_on = next(i for i, e in enumerate(order) if e.text == "-> CYCLE_ON")
    cycle_off = next(i for i, e in enumerate(order) if e.text == "-> CYCLE_OFF")
    closed = next(i for i, e in enumerate(order) if e.text == "Send_Pos_Off: closed")
    assert first_pose < cycle_on < cycle_off < closed
    assert box.behaviour.state.value == "idle"
    summary = result.format_summary()
    assert "p50" in summary and "p99" in summary and "jitter" in summary and "OK: clean session" in summary
    assert "-> CYCLE_ON  <- CYCLE_ON 0000" in result.format_timeline()


def test_e4_canonical_session_with_the_1_s_wait(box):
    result = run_robot(RobotSession(box.address, FAST, duration=0.3, extension=True, program_index=42))
    assert result.ok, result.reason
    assert result.steps == E4_STEPS
    assert commands(result) == ["-> PROG_IDX value=42", "-> CYCLE_ON", "-> CYCLE_OFF", "-> VISION_RESULT"]
    assert result.prog_idx_answer == 42 and result.vision_result == 1
    order = sorted(result.timeline, key=lambda e: e.t_ms)
    closed = next(e for e in order if e.text == "Send_Pos_Off: closed")
    asked = next(e for e in order if e.text == "-> VISION_RESULT")
    assert asked.t_ms - closed.t_ms >= 1000.0  # E4: wait 1 s after Send_Pos_Off
    assert box.behaviour.prog_idx == 42


def test_ping_and_separate_stream_target(box):
    result = play(box.address, ping=True, stream_target=f"127.0.0.1:{box.tcp_port}")
    assert result.ok, result.reason
    assert commands(result)[0] == "-> NONE"


# -- the box's verdicts ----------------------------------------------------------------------------------------


def test_not_ready_box_exit_3():
    with BoxThread(BoxConfig(not_ready=True), udp=False) as b:
        result = play(b.address)
    assert result.exit_code == EXIT_NOT_READY
    assert "box not ready" in result.reason


def test_progidx_409_exit_3():
    with BoxThread(BoxConfig(progidx_conflict=True), udp=False) as b:
        result = play(b.address, extension=True)
    assert result.exit_code == EXIT_NOT_READY and "409" in result.reason


@pytest.mark.parametrize("code", [2, 202, 409])
def test_vision_results_are_reported(code):
    with BoxThread(BoxConfig(vision_result=code), udp=False) as b:
        result = play(b.address, extension=True, duration=0.1)
    assert result.ok and result.vision_result == code


def test_cycle_off_failure_exit_1():
    with BoxThread(BoxConfig(cycle_off_fails=True), udp=False) as b:
        result = play(b.address)
    assert result.exit_code == EXIT_MISBEHAVED
    assert result.reason == "CYCLE_OFF answered 0x0002 where 0000 expected (S1)"


def test_slow_box_times_out_exit_4():
    with BoxThread(BoxConfig(latency_ms=600), udp=False) as b:
        result = play(b.address, profile=Profile(time_out_ms=200))
    assert result.exit_code == EXIT_TIMEOUT and "time_out 200 ms (T1)" in result.reason


def test_connection_refused_exit_5():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    result = play(("127.0.0.1", port))
    assert result.exit_code == EXIT_CONNECTION and "refused" in result.reason


# -- broken boxes ------------------------------------------------------------------------------------------------


class FakeBox:
    """A threaded TCP box whose answers come from ``respond(frame) -> bytes | None | "close"``."""

    def __init__(self, respond):
        self.respond = respond

    def __enter__(self):
        respond = self.respond

        class Handler(socketserver.BaseRequestHandler):
            def handle(self):
                decoder = StreamDecoder(DEFAULT_PROFILE, TransferType.ROBOT_TO_BOX)
                self.request.settimeout(10)
                while True:
                    try:
                        data = self.request.recv(65536)
                    except OSError:
                        return
                    if not data:
                        return
                    for event in decoder.feed(data):
                        out = respond(event) if isinstance(event, Frame) else None
                        if out == "close":
                            return
                        if out:
                            self.request.sendall(out)

        class Server(socketserver.ThreadingTCPServer):
            daemon_threads = True
            allow_reuse_address = True

        self.server = Server(("127.0.0.1", 0), Handler)
        self.thread = threading.Thread(target=self.server.serve_forever, kwargs={"poll_interval": 0.05}, daemon=True)
        self.thread.start()
        self.address = self.server.server_address
        return self

    def __exit__(self, *exc):
        self.server.shutdown()
        self.server.server_close()


def good(frame):
    if frame.action is Action.PROG_IDX:
        return encode(answer(frame.action, 0, frame.blocks))
    if frame.action is Action.VISION_RESULT:
        return encode(answer(frame.action, 0, value_blocks([1])))
    return encode(answer(frame.action))


@pytest.mark.parametrize("respond,code,words", [
    (lambda f: encode(answer(Action.NONE)) if f.action is Action.CYCLE_ON else good(f), EXIT_MISBEHAVED,
     "CYCLE_ON answered with action NONE (A2"),
    (lambda f: encode(answer(f.action, 0x1001)) if f.action is Action.CYCLE_ON else good(f), EXIT_MISBEHAVED,
     "CYCLE_ON answered 0x1001 where 0000 expected"),
    (lambda f: b"\xfe\xfe\x00\x01\x01" + good(f)[5:] if f.action is Action.CYCLE_ON else good(f), EXIT_MISBEHAVED,
     "malformed answer to CYCLE_ON: [F3]"),
    (lambda f: good(f)[:-2] + b"\x12\x34" if f.action is Action.CYCLE_OFF else good(f), EXIT_MISBEHAVED,
     "malformed answer to CYCLE_OFF: [F6]"),
    (lambda f: None if f.action is Action.CYCLE_ON else good(f), EXIT_TIMEOUT, "no answer to CYCLE_ON within time_out"),
    (lambda f: "close" if f.action is Action.CYCLE_OFF else good(f), EXIT_CONNECTION,
     "the box closed the command connection while CYCLE_OFF"),
    (lambda f: encode(answer(f.action, 0x1001)) if f.action is Action.POSE else good(f), EXIT_MISBEHAVED,
     "pose #0 answered 0x1001 where 0000 expected (S3)"),
    (lambda f: good(f) * 2 if f.action is Action.CYCLE_ON else good(f), EXIT_MISBEHAVED,
     "unsolicited frame on the command connection"),
    (lambda f: "close" if f.action is Action.POSE else good(f), EXIT_CONNECTION, "stream connection"),
])
def test_broken_boxes_give_one_line_reasons(respond, code, words):
    with FakeBox(respond) as fake:
        result = play(fake.address, profile=Profile(time_out_ms=1500), duration=0.2)
    assert result.exit_code == code, result.reason
    assert words in result.reason
    assert "\n" not in result.reason


def test_result_code_404_from_the_box_is_a_violation():
    def respond(frame):
        if frame.action is Action.VISION_RESULT:
            return encode(answer(frame.action, 0, value_blocks([404])))
        return good(frame)

    with FakeBox(respond) as fake:
        result = play(fake.address, extension=True, duration=0.1)
    assert result.exit_code == EXIT_MISBEHAVED and "404" in result.reason and "E3" in result.reason


def test_vision_time_out_is_separate_from_time_out():
    def respond(frame):
        return None if frame.action is Action.VISION_RESULT else good(frame)

    with FakeBox(respond) as fake:
        result = play(fake.address, profile=Profile(time_out_ms=2000, vision_time_out_ms=300), extension=True,
                      duration=0.1)
    assert result.exit_code == EXIT_TIMEOUT and "vision_time_out 300 ms" in result.reason


# -- deliberately broken robots against the reference box ------------------------------------------------------------


@pytest.mark.parametrize("faults,clause_code", [
    (RobotFaults(float_byte_order="little"), None),  # mostly undetectable: swapped floats are still numbers
    (RobotFaults(first_index=1), 0x1001),
    (RobotFaults(block_length=24), 0x1001),
])
def test_broken_robot_frames(box, faults, clause_code):
    result = play(box.address, faults=faults, stop_on_error=False, duration=0.2)
    answers = {e.answer for e in result.timeline if e.text.startswith("-> POSE")}
    if clause_code is None:
        # swapped floats are numbers all the same, unless their bytes happen to read as NaN/inf
        assert answers <= {"POSE 0000", "POSE 1001"}
    else:
        assert answers == {f"POSE {clause_code:04X}"}
        assert result.exit_code == EXIT_MISBEHAVED
        assert result.poses_answered == result.poses_sent  # stop_on_error=False: the session went on
        assert commands(result) == ["-> CYCLE_ON", "-> CYCLE_OFF"]


def test_little_endian_floats_reach_the_box_byte_swapped(box):
    seen = []

    def hook(frame, data):
        seen.append(data)
        return data

    result = play(box.address, faults=RobotFaults(float_byte_order="little", encode_hook=hook), duration=0.1,
                  stop_on_error=False)
    assert result.poses_answered == result.poses_sent  # swapped floats mostly read as (wrong) finite numbers
    pose = next(d for d in seen if d[5] == Action.POSE)
    assert pose[13:17] == struct.pack("<f", 800.0)  # x of the home pose


def test_bursty_drifting_segmented_stream_is_still_answered(box):
    result = play(box.address, faults=RobotFaults(burst=4, drift=0.5, segment_size=3), duration=0.4)
    assert result.ok, result.reason
    intervals = result.send_intervals_ms
    assert min(intervals) < 2.0 < 40.0 < max(intervals)  # back-to-back within a burst, long gaps between


def test_stream_left_open(box):
    result = play(box.address, faults=RobotFaults(leave_stream_open=True, stream_hold_s=0.3))
    assert result.ok
    assert any("left open" in e.text for e in result.timeline)


def test_encode_hook_breaking_the_direction_times_out(box):
    def hook(frame, data):
        return data[:4] + b"\x10" + data[5:] if frame.action is Action.CYCLE_ON else data

    result = play(box.address, profile=Profile(time_out_ms=300), faults=RobotFaults(encode_hook=hook))
    assert result.exit_code == EXIT_TIMEOUT and "CYCLE_ON" in result.reason


def test_custom_steps_and_validation(box):
    result = play(box.address, steps=("connect", "cycle_off", "disconnect"))
    assert result.ok and commands(result) == ["-> CYCLE_OFF"]
    with pytest.raises(ValueError, match="unknown session steps"):
        RobotSession(box.address, steps=("connect", "dance"))
    with pytest.raises(ValueError):
        RobotFaults(burst=0)
    with pytest.raises(ValueError):
        RobotSession(box.address, duration=0)


@pytest.mark.parametrize("text,want", [
    ("127.0.0.1:9004", ("127.0.0.1", 9004)), ("localhost", ("localhost", 9004)), ("[::1]:5000", ("::1", 5000)),
    ("[::1]", ("::1", 9004)), ("box.local:1", ("box.local", 1)),
])
def test_parse_target(text, want):
    assert parse_target(text) == want


@pytest.mark.parametrize("text", ["", ":9004", "host:", "host:port", "host:0", "host:70000", "[::1", "[::1]x",
                                  "[::1]:"])
def test_parse_target_rejects(text):
    with pytest.raises(ValueError):
        parse_target(text)


# -- the robot command ------------------------------------------------------------------------------------------------


def test_cli_robot_clean_session(box, capsys):
    code = main(["robot", "--target", f"127.0.0.1:{box.tcp_port}", "--duration", "0.2", "--time-out", "1000"])
    out = capsys.readouterr().out
    assert code == 0
    assert "-> CYCLE_ON  <- CYCLE_ON 0000" in out and "OK: clean session (exit 0)" in out


def test_cli_robot_extension_quiet(box, capsys):
    code = main(["robot", "--target", f"127.0.0.1:{box.tcp_port}", "--duration", "0.1", "--extension",
                 "--result-wait", "0.1", "-q"])
    out = capsys.readouterr().out
    assert code == 0 and "vision result: 1 (OK)" in out and "-> POSE" not in out


def test_cli_robot_not_ready_exit_3(capsys):
    with BoxThread(BoxConfig(not_ready=True), udp=False) as b:
        code = main(["robot", "--target", f"127.0.0.1:{b.tcp_port}", "-q"])
    err = capsys.readouterr().err
    assert code == 3 and err.strip().startswith("isight-conformance robot: box not ready")


@pytest.mark.parametrize("args", [["--target", "nohost:"], ["--target", "x:1", "--duration", "-1"],
                                  ["--target", "x:1", "--pose-rate", "0"]])
def test_cli_robot_bad_arguments_exit_2(args, capsys):
    assert main(["robot", *args]) == 2
    assert len(capsys.readouterr().err.strip().splitlines()) == 1


def test_cli_robot_refused_exit_5(capsys):
    with contextlib.closing(socket.socket()) as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    assert main(["robot", "--target", f"127.0.0.1:{port}", "-q"]) == 5
    assert "refused" in capsys.readouterr().err

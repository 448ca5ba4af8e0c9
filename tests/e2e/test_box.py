"""The reference box over loopback: TCP and UDP, knobs, bounded resources, the serve command."""

import asyncio
import contextlib
import json
import os
import re
import signal
import socket
import struct
import subprocess
import sys
import time
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from conformance.commands import main
from conformance.endpoints.behaviour import BoxConfig
from conformance.endpoints.loop import BoxThread
from conformance.endpoints.server import ReferenceBox
from conformance.protocol import (
    DEFAULT_PROFILE,
    Action,
    Frame,
    Header,
    Profile,
    StreamDecoder,
    TransferType,
    Transport,
    answer,
    codec_for,
    encode,
    encode_raw,
    pose_blocks,
    request,
    tolerance_blocks,
    value_blocks,
)

pytestmark = pytest.mark.timeout(60)

ROOT = Path(__file__).resolve().parents[2]
POSE = (812.5, -100.25, 250.0, 180.0, 4.5, -0.5)
POSE_FRAME = encode(request(Action.POSE, pose_blocks([POSE])))


def req(action, blocks=(), profile=DEFAULT_PROFILE):
    return encode(request(action, blocks), profile)


@pytest.fixture(scope="module")
def shared_box():
    with BoxThread(BoxConfig()) as box:
        yield box


@contextlib.contextmanager
def connect(box, timeout=5.0):
    sock = socket.create_connection(box.address, timeout=timeout)
    sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
    try:
        yield sock
    finally:
        sock.close()


def read_frames(sock, count, profile=DEFAULT_PROFILE, timeout=5.0):
    """Up to ``count`` answer frames (fewer if the box closes or ``timeout`` passes)."""
    decoder = StreamDecoder(profile, TransferType.BOX_TO_ROBOT)
    out = []
    deadline = time.monotonic() + timeout
    while len(out) < count:
        remaining = deadline - time.monotonic()
        if remaining <= 0:
            break
        sock.settimeout(remaining)
        try:
            data = sock.recv(65536)
        except (TimeoutError, ConnectionResetError):
            break
        if not data:
            break
        out += decoder.feed(data)
    for event in out:
        assert isinstance(event, Frame), f"malformed answer from the box: {event}"
    return out


def exchange(box, data, count=1, profile=DEFAULT_PROFILE):
    with connect(box) as sock:
        sock.sendall(data)
        return read_frames(sock, count, profile)


def assert_silent(sock, wait=0.3):
    sock.settimeout(wait)
    with pytest.raises(TimeoutError):
        data = sock.recv(1)
        pytest.fail(f"expected silence, got {data!r}")


def still_answers(box):
    answers = exchange(box, POSE_FRAME)
    assert [(a.action, a.error_code) for a in answers] == [(Action.POSE, 0)]


# -- TCP basics ----------------------------------------------------------------------------------------


def test_answers_a_pose(shared_box):
    still_answers(shared_box)


def test_split_byte_by_byte(shared_box):
    frames = [req(Action.NONE), POSE_FRAME, req(Action.TOLERANCE, tolerance_blocks([0.5])), POSE_FRAME]
    data = b"".join(frames)
    with connect(shared_box) as sock:
        for i in range(len(data)):
            sock.send(data[i : i + 1])
        answers = read_frames(sock, 4)
    assert [(a.action, a.error_code) for a in answers] == [
        (Action.NONE, 0), (Action.POSE, 0), (Action.TOLERANCE, 0), (Action.POSE, 0)]


def test_coalesced_frames_each_answered(shared_box):
    answers = exchange(shared_box, POSE_FRAME * 200 + req(Action.NONE) + POSE_FRAME * 3, count=204)
    assert len(answers) == 204
    assert [a.action for a in answers[199:]] == [Action.POSE, Action.NONE, Action.POSE, Action.POSE, Action.POSE]
    assert all(a.error_code == 0 for a in answers)


def test_garbage_is_skipped_silently_and_the_stream_resynchronises(shared_box):
    with connect(shared_box) as sock:
        sock.sendall(b"\x00\x01\x02 not a frame \xfe")
        assert_silent(sock)
        sock.sendall(encode_raw(Header(version=7)) + encode_raw(Header(action=0x42)) + POSE_FRAME)
        answers = read_frames(sock, 1)
        assert [(a.action, a.error_code) for a in answers] == [(Action.POSE, 0)]
        assert_silent(sock, 0.2)


@pytest.mark.parametrize("data,code", [
    (encode_raw(Header(action=0x23, block_type=1, block_count=1, block_length=25), bytes([1]) + bytes(24)), 0x1001),
    (encode_raw(Header(action=0x23, block_type=1, block_count=1, block_length=25),
                bytes([0]) + struct.pack(">6f", float("nan"), 0, 0, 0, 0, 0)), 0x1001),
    (encode_raw(Header(action=0x24, block_type=2, block_count=1, block_length=5), bytes(5)), 0x1001),
    (encode_raw(Header(action=0x25, block_type=0, block_count=0, block_length=0)), 0x1002),
    (encode_raw(Header(action=0x25, block_type=2, block_count=2, block_length=5), bytes(5) + bytes([0]) + bytes(4)),
     0x1002),
], ids=["pose-index", "pose-nan", "register-pose-shape", "tolerance-missing", "tolerance-index"])
def test_malformed_requests_get_their_error_never_0000(shared_box, data, code):
    answers = exchange(shared_box, data + POSE_FRAME, count=2)
    assert [(a.action, a.error_code) for a in answers] == [(data[5], code), (Action.POSE, 0)]


def test_command_connection_not_delayed_by_a_silent_stream(shared_box):
    with connect(shared_box) as stream, connect(shared_box) as cmd:
        stream.sendall(POSE_FRAME[:20])  # a pose left hanging
        cmd.sendall(req(Action.NONE))
        assert [a.action for a in read_frames(cmd, 1)] == [Action.NONE]
        stream.sendall(POSE_FRAME[20:])
        assert [a.action for a in read_frames(stream, 1)] == [Action.POSE]


def test_hundred_connect_disconnect_cycles(shared_box):
    for _ in range(100):
        with connect(shared_box) as sock:
            sock.sendall(POSE_FRAME)
            assert len(read_frames(sock, 1)) == 1
    still_answers(shared_box)
    deadline = time.monotonic() + 5
    while shared_box.call(lambda: len(shared_box.box.connections)) and time.monotonic() < deadline:
        time.sleep(0.02)
    assert shared_box.call(lambda: len(shared_box.box.connections)) == 0  # S5: freed


def test_the_box_closes_after_the_robot_closes(shared_box):
    with connect(shared_box) as sock:
        sock.sendall(POSE_FRAME)
        sock.shutdown(socket.SHUT_WR)
        assert len(read_frames(sock, 1)) == 1
        sock.settimeout(5)
        assert sock.recv(10) == b""  # the box closed its side (S5)


# -- UDP ----------------------------------------------------------------------------------------------------


@pytest.mark.parametrize("profile", [Profile(), Profile(crc="xmodem"), Profile(crc="x-25", crc_byte_order="little")],
                         ids=["modbus", "xmodem", "x25-little"])
def test_udp_with_crc_settings(profile):
    codec = codec_for(profile)
    with BoxThread(BoxConfig(profile=profile)) as box, socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        assert box.udp_port == box.tcp_port
        sock.settimeout(5)
        target = ("127.0.0.1", box.udp_port)
        pose = codec.encode(request(Action.POSE, pose_blocks([POSE])), Transport.UDP)
        sock.sendto(pose, target)
        answer = codec.parse(sock.recv(100), Transport.UDP, TransferType.BOX_TO_ROBOT)
        assert (answer.action, answer.error_code) == (Action.POSE, 0)
        # a wrong CRC and a TCP-style check are dropped: the next datagram back answers the CycleOn
        sock.sendto(pose[:-2] + bytes([pose[-2] ^ 0x55, pose[-1]]), target)
        sock.sendto(encode(request(Action.POSE, pose_blocks([POSE]))), target)
        sock.sendto(codec.encode(request(Action.CYCLE_ON), Transport.UDP), target)
        answer = codec.parse(sock.recv(100), Transport.UDP, TransferType.BOX_TO_ROBOT)
        assert (answer.action, answer.error_code) == (Action.CYCLE_ON, 0)
        assert box.behaviour.stats.dropped_datagrams == 2


# -- knobs ---------------------------------------------------------------------------------------------------


def test_not_ready_answers_0001():
    with BoxThread(BoxConfig(not_ready=True)) as box:
        answers = exchange(box, req(Action.CYCLE_ON) + POSE_FRAME, 2)
        assert [(a.action, a.error_code) for a in answers] == [(Action.CYCLE_ON, 1), (Action.POSE, 0)]


def test_cycle_off_fails_answers_0002():
    with BoxThread(BoxConfig(cycle_off_fails=True)) as box:
        answers = exchange(box, req(Action.CYCLE_ON) + req(Action.CYCLE_OFF), 2)
        assert [a.error_code for a in answers] == [0, 2]


@pytest.mark.parametrize("code", [1, 2, 10, 20, 202, 400, 409])
def test_vision_result_codes(code):
    with BoxThread(BoxConfig(vision_result=code), udp=False) as box:
        (answer,) = exchange(box, req(Action.VISION_RESULT))
        assert (answer.action, answer.error_code, answer.blocks[0].value) == (Action.VISION_RESULT, 0, code)


def test_progidx_conflict_409():
    with BoxThread(BoxConfig(progidx_conflict=True), udp=False) as box:
        (answer,) = exchange(box, req(Action.PROG_IDX, value_blocks([12])))
        assert (answer.error_code, answer.blocks[0].value) == (0, 409)


def test_no_extension_is_silent_on_26_27():
    with BoxThread(BoxConfig(extension=False), udp=False) as box, connect(box) as sock:
        sock.sendall(req(Action.VISION_RESULT) + req(Action.PROG_IDX, value_blocks([1])))
        assert_silent(sock)
        sock.sendall(POSE_FRAME)
        assert [a.action for a in read_frames(sock, 1)] == [Action.POSE]


def test_latency_keeps_order():
    with BoxThread(BoxConfig(latency_ms=150), udp=False) as box, connect(box) as sock:
        t0 = time.monotonic()
        sock.sendall(req(Action.NONE))
        time.sleep(0.05)
        sock.sendall(POSE_FRAME + req(Action.CYCLE_ON))
        answers = read_frames(sock, 3)
        elapsed = time.monotonic() - t0
        assert [a.action for a in answers] == [Action.NONE, Action.POSE, Action.CYCLE_ON]
        assert elapsed >= 0.15  # the box cannot answer before the delay it was told to add


def test_close_on_garbage():
    with BoxThread(BoxConfig(on_garbage="close"), udp=False) as box, connect(box) as sock:
        sock.sendall(b"garbage!")
        sock.settimeout(5)
        with contextlib.suppress(ConnectionResetError):
            assert sock.recv(10) == b""
        still_answers(box)


# -- bounded resources (R5) --------------------------------------------------------------------------------------


def test_connection_limit_evicts_the_stalest_for_a_fresh_robot():
    with BoxThread(BoxConfig(), udp=False, max_connections=5, evict_after=0.2) as box:
        squatters = [socket.create_connection(box.address, timeout=5) for _ in range(5)]
        try:
            for s in squatters:
                s.sendall(POSE_FRAME[:11])  # partial frames left hanging
            time.sleep(0.4)
            still_answers(box)
            assert box.box.evicted >= 1
        finally:
            for s in squatters:
                s.close()


def test_connection_limit_refuses_when_nobody_is_stale():
    with BoxThread(BoxConfig(), udp=False, max_connections=3, evict_after=60) as box:
        holders = [socket.create_connection(box.address, timeout=5) for _ in range(3)]
        try:
            for h in holders:  # make sure all three are admitted before the fourth
                h.sendall(req(Action.NONE))
                assert len(read_frames(h, 1)) == 1
            with connect(box) as extra:
                extra.settimeout(5)
                with contextlib.suppress(ConnectionResetError):
                    assert extra.recv(10) == b""  # refused: closed at once
            assert box.box.refused == 1
        finally:
            for h in holders:
                h.close()
        deadline = time.monotonic() + 5
        while box.call(lambda: len(box.box.connections)) and time.monotonic() < deadline:
            time.sleep(0.02)
        still_answers(box)  # the slots are free again


def test_oversize_announcements_do_not_stop_a_fresh_connection(shared_box):
    huge = encode_raw(Header(action=0x23, block_type=1, block_count=255, block_length=0xFFFF))[:12]
    legal_but_hanging = encode_raw(Header(action=0x23, block_type=1, block_count=255, block_length=25))[:12]
    socks = []
    try:
        for i in range(60):
            s = socket.create_connection(shared_box.address, timeout=5)
            s.sendall((huge if i % 2 else legal_but_hanging) + bytes(3000))
            socks.append(s)
        still_answers(shared_box)
        answers = read_frames(socks[1], 1)  # the impossible header is answered 1001 (A3), then skipped
        assert [(a.action, a.error_code) for a in answers] == [(Action.POSE, 0x1001)]
    finally:
        for s in socks:
            s.close()


def test_unread_answers_pause_reading_not_the_box():
    with BoxThread(BoxConfig(), udp=False) as box:
        hog = socket.create_connection(box.address, timeout=5)
        hog.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
        hog.setblocking(False)
        chunk = POSE_FRAME * 1000

        def paused():
            return box.call(lambda: any(c.read_paused for c in box.box.connections.values()))

        deadline = time.monotonic() + 10
        try:
            while time.monotonic() < deadline:  # bounded: 10 s, and at most a few hundred MB
                try:
                    hog.send(chunk)
                except BlockingIOError:
                    if paused():  # the box stopped reading the hog: back-pressure reached us
                        break
                    time.sleep(0.01)
            assert paused()
            still_answers(box)
            conns = box.call(lambda: list(box.box.connections.values()))
            assert max(c.transport.get_write_buffer_size() for c in conns) < 1 << 20  # the hog's answers stay bounded
        finally:
            hog.close()


def test_idle_connections_are_closed():
    with BoxThread(BoxConfig(), udp=False, idle_timeout=0.2) as box, connect(box) as sock:
        sock.settimeout(5)
        with contextlib.suppress(ConnectionResetError):
            assert sock.recv(10) == b""
        assert box.box.idle_closed == 1


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(st.lists(st.one_of(
    st.binary(max_size=200),
    st.sampled_from([POSE_FRAME, POSE_FRAME[:17], b"\xfe\xfe", req(Action.CYCLE_ON), encode_raw(Header(version=9))]),
), max_size=8))
def test_generated_bytes_never_stop_the_box(shared_box, parts):
    data = b"".join(parts)
    with connect(shared_box) as sock:
        sock.sendall(data)
        # R1: whatever came back, no answer to a non-pose/garbage stream is malformed
        sock.settimeout(0.05)
        with contextlib.suppress(TimeoutError, ConnectionResetError):
            sock.recv(65536)
    still_answers(shared_box)  # R2


# -- APIs -----------------------------------------------------------------------------------------------------------


def test_reference_box_async_api():
    async def scenario():
        async with ReferenceBox(BoxConfig(), host="127.0.0.1", port=0) as box:
            assert box.tcp_port and box.udp_port == box.tcp_port
            reader, writer = await asyncio.open_connection(*box.address)
            writer.write(POSE_FRAME)
            data = await asyncio.wait_for(reader.readexactly(14), 5)
            writer.close()
            return data, box.describe()

    data, line = asyncio.run(scenario())
    assert data == encode(Frame(TransferType.BOX_TO_ROBOT, Action.POSE))
    assert re.fullmatch(r"listening tcp 127\.0\.0\.1:(\d+) udp 127\.0\.0\.1:\1", line)


def test_ipv6_loopback():
    if not socket.has_ipv6:
        pytest.skip("no IPv6")
    try:
        box = BoxThread(BoxConfig(), host="::1").start()
    except OSError:
        pytest.skip("::1 not available")
    try:
        assert box.address[0] == "::1"
        sock = socket.create_connection(box.address, timeout=5)
        with sock:
            sock.sendall(POSE_FRAME)
            assert len(read_frames(sock, 1)) == 1
        assert box.box.describe().startswith(f"listening tcp [::1]:{box.tcp_port} udp [::1]:")
    finally:
        box.stop()


def test_frame_log(tmp_path):
    log = tmp_path / "frames.jsonl"
    with BoxThread(BoxConfig(), log=str(log)) as box:
        exchange(box, b"xyz" + POSE_FRAME, 1)
        bad = encode_raw(Header(action=0x25, block_type=2, block_count=1, block_length=5), bytes([3]) + bytes(4))
        exchange(box, bad, 1)
    records = [json.loads(line) for line in log.read_text().splitlines()]
    dirs = [r["direction"] for r in records]
    assert dirs.count("open") == 2 and dirs.count("close") == 2
    ins = [r for r in records if r["direction"] == "in"]
    outs = [r for r in records if r["direction"] == "out"]
    assert ins[0]["error"]["clause"] == "F1" and ins[0]["hex"] == b"xyz".hex() and ins[0]["decision"] == "silent"
    assert ins[1]["hex"] == POSE_FRAME.hex() and "POSE" in ins[1]["frame"]
    assert ins[2]["error"]["clause"] == "B3" and "A3" in ins[2]["note"]
    assert [o["hex"][20:24] for o in outs] == ["0000", "1002"]
    assert all(isinstance(r["t"], float) and "conn" in r for r in records)


# -- the serve command ------------------------------------------------------------------------------------------------


def _serve(*args):
    env = dict(os.environ, PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    return subprocess.Popen([sys.executable, "-m", "conformance", "serve", *args], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, env=env)


def test_serve_port_0_prints_its_port_and_sigterm_exits_0_with_the_log_flushed(tmp_path):
    log = tmp_path / "serve.jsonl"
    proc = _serve("--port", "0", "--log", str(log), "--latency-ms", "1")
    try:
        line = proc.stdout.readline()
        match = re.fullmatch(r"listening tcp 127\.0\.0\.1:(\d+) udp 127\.0\.0\.1:(\d+)\n", line)
        assert match, line
        port = int(match.group(1))
        assert port != 0 and match.group(2) == match.group(1)
        with socket.create_connection(("127.0.0.1", port), timeout=5) as sock:
            sock.sendall(POSE_FRAME)
            assert len(read_frames(sock, 1)) == 1
            proc.send_signal(signal.SIGTERM)
            assert proc.wait(10) == 0
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait(5)
    assert "stopped" in proc.stderr.read()
    records = [json.loads(x) for x in log.read_text().splitlines()]
    assert [r["direction"] for r in records][:3] == ["open", "in", "out"]
    assert records[1]["hex"] == POSE_FRAME.hex()


def test_serve_sigint_and_no_udp():
    proc = _serve("--port", "0", "--no-udp", "--idle-timeout", "0")
    try:
        line = proc.stdout.readline()
        assert re.fullmatch(r"listening tcp 127\.0\.0\.1:\d+\n", line), line
        proc.send_signal(signal.SIGINT)
        assert proc.wait(10) == 0
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait(5)


def test_serve_port_in_use_is_one_line(capsys):
    with socket.socket() as holder:
        holder.bind(("127.0.0.1", 0))
        holder.listen()
        port = holder.getsockname()[1]
        assert main(["serve", "--port", str(port), "--no-udp"]) == 1
    err = capsys.readouterr().err.strip()
    assert err.startswith("isight-conformance serve:") and len(err.splitlines()) == 1


@pytest.mark.parametrize("args", [["--port", "70000"], ["--latency-ms", "-5"], ["--max-connections", "0"],
                                  ["--crc", "modbus", "--first-index", "0", "--time-out", "0"]])
def test_serve_bad_values_exit_2(args, capsys):
    assert main(["serve", *args]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and err.startswith("isight-conformance serve:")


def test_half_close_with_latency_still_delivers_held_answers() -> None:
    """A1/S5: with --latency-ms, a request followed by the robot's FIN is still answered, then closed."""
    with BoxThread(BoxConfig(latency_ms=50)) as box:
        s = socket.create_connection(("127.0.0.1", box.tcp_port), timeout=5)
        s.sendall(encode(request(Action.NONE)))
        s.shutdown(socket.SHUT_WR)
        got = b""
        while chunk := s.recv(100):
            got += chunk
        s.close()
    assert got == encode(answer(Action.NONE))

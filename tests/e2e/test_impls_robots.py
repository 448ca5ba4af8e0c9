"""The independent robots (tests/impls) send what they should: captured by a tiny recording box."""

from __future__ import annotations

import contextlib
import math
import socket
import struct
import subprocess
import sys
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path

import pytest

from tests.impls.expectations import EXPECTATIONS
from tests.impls.robot import ROBOTS, run_robot
from tests.impls.robots import Outcome, Robot

ROOT = Path(__file__).resolve().parents[2]
DURATION = 0.4


@dataclass
class Conn:
    sock: socket.socket
    opened: float
    frames: list[tuple[float, bytes]] = field(default_factory=list)
    eof: float | None = None

    @property
    def port(self) -> int:
        return int(self.sock.getpeername()[1])

    def actions(self) -> list[int]:
        return [f[5] for _, f in self.frames]


class Recorder:
    """Accepts connections, records every frame, answers each request 0000 (26: the index, 27: ResultCode 1)."""

    def __init__(self) -> None:
        self.sock = socket.create_server(("127.0.0.1", 0))
        self.sock.settimeout(0.2)
        self.port = self.sock.getsockname()[1]
        self.conns: list[Conn] = []
        self.stop = threading.Event()
        self.threads = [threading.Thread(target=self._accept, daemon=True)]
        self.threads[0].start()

    def _accept(self) -> None:
        while not self.stop.is_set():
            try:
                sock, _ = self.sock.accept()
            except TimeoutError:
                continue
            conn = Conn(sock, time.monotonic())
            self.conns.append(conn)
            thread = threading.Thread(target=self._serve, args=(conn,), daemon=True)
            self.threads.append(thread)
            thread.start()

    def _serve(self, conn: Conn) -> None:
        buf = b""
        conn.sock.settimeout(0.2)
        while not self.stop.is_set():
            try:
                data = conn.sock.recv(65536)
            except TimeoutError:
                continue
            except OSError:
                break
            if not data:
                break
            buf += data
            while len(buf) >= 12:
                _, _, _, action, _, n, length, _ = struct.unpack(">HHBBBBHH", buf[:12])
                size = 14 + n * length
                if len(buf) < size:
                    break
                frame, buf = buf[:size], buf[size:]
                conn.frames.append((time.monotonic(), frame))
                with contextlib.suppress(OSError):
                    conn.sock.sendall(self.answer(action, frame))
        conn.eof = time.monotonic()

    @staticmethod
    def answer(action: int, frame: bytes) -> bytes:
        if action in (0x26, 0x27):
            value = frame[13:17] if action == 0x26 else struct.pack(">i", 1)
            return struct.pack(">HHBBBBHH", 0xFEFE, 1, 0x10, action, 3, 1, 5, 0) + b"\0" + value + b"\0\0"
        return struct.pack(">HHBBBBHH", 0xFEFE, 1, 0x10, action, 0, 0, 0, 0) + b"\0\0"

    def close(self) -> None:
        self.stop.set()
        for t in self.threads:
            t.join(5)
        for c in self.conns:
            c.sock.close()
        self.sock.close()


@pytest.fixture
def recorder():  # type: ignore[no-untyped-def]
    r = Recorder()
    yield r
    r.close()


@pytest.fixture
def closes(monkeypatch: pytest.MonkeyPatch) -> list[int]:
    """The robot's local ports in the order it closes its connections (FINs from two
    connections reach two reader threads in no reliable order, so the robot is watched)."""
    order: list[int] = []
    real = Robot._close

    def watched(sock: socket.socket | None) -> None:
        if sock is not None and sock.fileno() >= 0:
            port = sock.getsockname()[1]
            if port not in order:
                order.append(port)
        real(sock)

    monkeypatch.setattr(Robot, "_close", staticmethod(watched))
    return order


def play(recorder: Recorder, name: str, **overrides: object) -> tuple[Outcome, list[Conn]]:
    outcome = run_robot(name, ("127.0.0.1", recorder.port), duration=DURATION, **overrides)
    deadline = time.monotonic() + 5
    while any(c.eof is None for c in recorder.conns) and time.monotonic() < deadline:
        time.sleep(0.02)
    return outcome, recorder.conns


def poses(conn: Conn) -> list[tuple[int, int, tuple[float, ...]]]:
    """(transfer type, first index, the six floats read big-endian) of every pose frame."""
    return [(f[4], f[12], struct.unpack(">6f", f[13:37])) for _, f in conn.frames if f[5] == 0x23]


def first_time(conn: Conn, action: int) -> float:
    return next(t for t, f in conn.frames if f[5] == action)


def test_canonical_session(recorder: Recorder, closes: list[int]) -> None:
    outcome, (cmd, stream) = play(recorder, "canonical")
    assert outcome.exit_code == 0, outcome.reason
    assert cmd.actions() == [0x01, 0x02]
    assert stream.actions() and set(stream.actions()) == {0x23}
    assert stream.opened < first_time(cmd, 0x01)  # stream on, then CycleOn (S1)
    assert any(first_time(cmd, 0x01) < t < first_time(cmd, 0x02) for t, _ in stream.frames)  # poses keep flowing
    assert closes == [stream.port, cmd.port]  # stream off, then disconnect
    assert all(tt == 0x01 and index == 0 and all(math.isfinite(v) for v in p) for tt, index, p in poses(stream))
    assert poses(stream)[0][2] == (800.0, 0.0, 500.0, 180.0, 0.0, 0.0)
    assert all(f[:4] == b"\xfe\xfe\x00\x01" and f[-2:] == b"\0\0" for c in (cmd, stream) for _, f in c.frames)


def test_karel_calls_session(recorder: Recorder, closes: list[int]) -> None:
    outcome, (cmd, stream) = play(recorder, "karel-calls")
    assert outcome.exit_code == 0, outcome.reason
    assert cmd.actions() == [0x00, 0x25, 0x23, 0x24, 0x01, 0x02]
    tol = next(f for _, f in cmd.frames if f[5] == 0x25)
    assert tol[7] == 3 and [tol[12 + 5 * i] for i in range(3)] == [0, 1, 2]
    assert stream.opened < first_time(cmd, 0x23)
    assert closes == [stream.port, cmd.port]


def test_extension_session(recorder: Recorder) -> None:
    outcome, (cmd, stream) = play(recorder, "extension")
    assert outcome.exit_code == 0, outcome.reason
    assert cmd.actions() == [0x26, 0x01, 0x02, 0x27]
    assert first_time(cmd, 0x26) < stream.opened
    assert stream.eof is not None and stream.eof < first_time(cmd, 0x27)  # result request after Send_Pos_Off


@pytest.mark.parametrize(("name", "check"), [
    ("transfer-10", lambda cmd, stream: all(f[4] == 0x10 for c in (cmd, stream) for _, f in c.frames)),
    ("index-1", lambda cmd, stream: {index for _, index, _ in poses(stream)} == {1}),
    ("little-floats", lambda cmd, stream: poses(stream)[0][2][0] != 800.0
     and struct.unpack("<f", stream.frames[0][1][13:17])[0] == 800.0),
    ("nan-pose", lambda cmd, stream: sum(math.isnan(p[0]) for _, _, p in poses(stream)) == 1),
    ("cycle-on-first", lambda cmd, stream: first_time(cmd, 0x01) < stream.opened),
])
def test_broken_robots_send_their_defect(recorder: Recorder, name: str, check) -> None:  # type: ignore[no-untyped-def]
    _, conns = play(recorder, name, time_out=1.0)
    assert len(conns) == 2
    assert check(*conns)


def test_slow_stream_sends_below_the_declared_rate(recorder: Recorder) -> None:
    outcome, (cmd, stream) = play(recorder, "slow-stream", rate="50")
    assert outcome.exit_code == 0, outcome.reason
    sent = len(stream.frames)
    span = stream.frames[-1][0] - stream.frames[0][0]
    assert sent >= 5 and (sent - 1) / span < 0.85 * 50  # 35 Hz; a loaded machine only sends fewer


def test_stream_open_keeps_the_stream_until_the_box_closes_it(recorder: Recorder) -> None:
    result: list[Outcome] = []
    thread = threading.Thread(target=lambda: result.append(
        run_robot("stream-open", ("127.0.0.1", recorder.port), duration=DURATION)), daemon=True)
    thread.start()
    deadline = time.monotonic() + 20
    while (len(recorder.conns) < 2 or recorder.conns[0].eof is None) and time.monotonic() < deadline:
        time.sleep(0.02)
    cmd, stream = recorder.conns
    assert cmd.eof is not None
    time.sleep(0.5)
    assert stream.eof is None and thread.is_alive()  # the command is gone, the stream stays
    stream.sock.shutdown(socket.SHUT_RDWR)  # the box closes it: the robot ends
    thread.join(10)
    assert not thread.is_alive() and result[0].exit_code == 0


def test_robot_stops_on_a_silent_box() -> None:
    with socket.create_server(("127.0.0.1", 0)) as server:
        port = server.getsockname()[1]
        outcome = run_robot("canonical", ("127.0.0.1", port), duration=DURATION, time_out=0.5)
        assert outcome.exit_code == 4 and "no answer" in outcome.reason


def test_every_robot_has_an_expectation() -> None:
    for name, variant in ROBOTS.items():
        exp = EXPECTATIONS[name]
        assert exp.role == "robot" and exp.conforming == variant.conforming
        assert variant.conforming or (exp.clauses[0] == variant.clause and exp.level == variant.level)
        assert "--extension" not in exp.suite_args  # certify-robot judges the session the robot runs (E4 or S1)


def test_robot_command_line(recorder: Recorder) -> None:
    ok = subprocess.run([sys.executable, "-m", "tests.impls.robot", "canonical", "--target",
                         f"127.0.0.1:{recorder.port}", "--duration", str(DURATION)],
                        cwd=ROOT, capture_output=True, text=True, timeout=60)
    assert ok.returncode == 0 and "clean session" in ok.stdout
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        free = s.getsockname()[1]
    refused = subprocess.run([sys.executable, "-m", "tests.impls.robot", "canonical", "--target", f"127.0.0.1:{free}"],
                             cwd=ROOT, capture_output=True, text=True, timeout=60)
    assert refused.returncode == 5 and len(refused.stderr.strip().splitlines()) == 1
    bad = subprocess.run([sys.executable, "-m", "tests.impls.robot", "canonical", "--target", "nonsense"],
                         cwd=ROOT, capture_output=True, text=True, timeout=60)
    assert bad.returncode == 2 and bad.stderr.startswith("error:")


# -- the robot's knobs (its legal choices) -------------------------------------------------------------------
def test_knobs_several_cycles_pings_poses_and_tolerances_on_the_command_connection(recorder: Recorder) -> None:
    outcome, (cmd, stream) = play(recorder, "canonical", cycles="2", pings="3", cmd_poses="register",
                                  tolerance_at="in-cycle", tolerance_blocks="17")
    assert outcome.exit_code == 0, outcome.reason
    assert cmd.actions() == [0x00, 0x00, 0x24, 0x01, 0x00, 0x25, 0x02, 0x01, 0x02]
    tol = next(f for _, f in cmd.frames if f[5] == 0x25)
    assert tol[7] == 17 and [tol[12 + 5 * i] for i in range(17)] == list(range(17))
    assert stream.opened < first_time(cmd, 0x01) and stream.eof is not None


@pytest.mark.parametrize("writer", ["pieces", "bytes"])
def test_knob_writer_sends_frames_in_pieces_that_a_box_puts_together(recorder: Recorder, writer: str) -> None:
    outcome, (cmd, stream) = play(recorder, "canonical", writer=writer)
    assert outcome.exit_code == 0, outcome.reason
    assert cmd.actions() == [0x01, 0x02] and set(stream.actions()) == {0x23}


def test_random_robots_are_reproducible_and_ask_for_their_flags() -> None:
    from tests.impls.robot import variant
    from tests.impls.robots import KNOBS

    assert variant("random", 3).choices == variant("random", 3).choices
    seen = {k: {variant("random", s).choices.knobs()[k] for s in range(200)} for k in KNOBS}
    assert seen == {k: set(v) for k, v in KNOBS.items()}
    e4 = next(variant("random", s).choices for s in range(200) if variant("random", s).choices.session == "E4")
    assert "--extension" not in e4.suite_args()  # certify-robot's --extension auto judges E4 by its ProgIdx

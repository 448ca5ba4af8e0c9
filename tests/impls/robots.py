"""A threaded robot (client role) on plain sockets, like the KAREL programs would drive it.

``Robot(choices, ("127.0.0.1", port)).run()`` plays one session and returns an
:class:`Outcome`; every wait is bounded (``time_out``, ``vision_time_out``, the
trajectory) and ``stop()`` aborts from another thread. :data:`KNOBS` is the robot's
side of the legal-choice space (``conformance/protocol/legal.py``): pings, poses and
tolerances on the command connection, several cycles per session, requests written in
pieces, the stream's answers read late, the declared rate, S1 or E4;
:func:`random_choices` draws a legal combination from a seed. The command connection is
lock-step (send, then wait for the answer up to ``time_out``); the stream connection
sends poses on a fixed clock from its own thread while another thread reads the
answers, as they come or late, in bursts.
"""

from __future__ import annotations

import contextlib
import math
import random
import socket
import threading
import time
from dataclasses import dataclass, replace

from . import wire_format as wire
from .wire_format import Answer, encode_request, split_answers

HOME = (800.0, 0.0, 500.0, 180.0, 0.0, 0.0)
SPIN = 0.0015  # seconds before each pose's due time the stream thread stops sleeping and spins


#: knob -> its legal alternatives (the first is the default); the names are the legal table's robot knobs.
KNOBS: dict[str, tuple[str, ...]] = {
    "pings": ("0", "1", "3"),
    "cmd_poses": ("none", "pose", "register", "both"),
    "tolerance_at": ("none", "start", "in-cycle", "after-cycle"),
    "tolerance_blocks": ("1", "3", "17"),
    "cycles": ("1", "2", "3"),
    "writer": ("whole", "pieces", "bytes"),
    "read_late": ("as-they-come", "late"),
    "session": ("S1", "E4"),
    "rate": ("50", "20", "100"),
}
PIECE_PAUSE = 0.003  # writer "pieces": the header, then the rest this long after


@dataclass(frozen=True)
class RobotChoices:
    session: str = "S1"  # S1 | E4 | cycle-on-first (a defect: CycleOn before the stream is on)
    pings: str = "0"  # NONE requests: 1 before anything; 3: also after stream on and during the first cycle
    cmd_poses: str = "none"  # after stream on, on the command connection: ISIGHT(3,35) and/or ISIGHT(3,36)
    tolerance_at: str = "none"
    tolerance_blocks: str = "1"
    cycles: str = "1"  # CycleOn -> CycleOff pairs between stream on and stream off
    writer: str = "whole"
    read_late: str = "as-they-come"  # late: read the stream's answers in bursts every 0.5 s (pipelined, S6)
    rate: str = "50"  # the declared stream rate (Hz)
    rate_factor: float = 1.0  # the rate actually sent is rate_hz * rate_factor
    duration: float = 2.0  # primer trajectory, seconds
    time_out: float = 5.0
    vision_time_out: float = 5.0
    transfer: int = wire.ROBOT_TO_BOX
    first_index: int = 0
    float_order: str = ">"
    nan_pose: bool = False  # one pose in the middle of the trajectory carries NaN
    leave_stream_open: bool = False  # never close the stream connection
    no_wait: bool = False  # CycleOff 1 ms after CycleOn, before CycleOn's answer (an A1 defect), then both answers
    program_index: int = 7

    @property
    def rate_hz(self) -> float:
        return float(self.rate)

    def knobs(self) -> dict[str, str]:
        return {name: getattr(self, name) for name in KNOBS}

    def suite_args(self) -> tuple[str, ...]:
        """The certify-robot flags this robot's flag-decided choices need (none for E4: certify-robot judges the
        session the robot runs, ``--extension auto``)."""
        return ("--pose-rate", self.rate) if self.rate != "50" else ()


def random_choices(seed: int, base: RobotChoices | None = None) -> RobotChoices:
    """A legal combination of the knobs drawn from ``seed`` (on ``base``'s other settings)."""
    rng = random.Random(seed)
    drawn = {name: rng.choice(legal) for name, legal in KNOBS.items()}
    return replace(base or RobotChoices(), **drawn)  # type: ignore[arg-type]  # every value is a knob string


@dataclass
class Outcome:
    exit_code: int = 0
    reason: str = "clean session"
    poses_sent: int = 0
    poses_answered: int = 0
    commands: int = 0
    problems: int = 0


class SessionStop(Exception):
    def __init__(self, code: int, reason: str) -> None:
        super().__init__(reason)
        self.code = code
        self.reason = reason


class Robot:
    def __init__(self, choices: RobotChoices, target: tuple[str, int]) -> None:
        self.c = choices
        self.target = target
        self.outcome = Outcome()
        self.stopping = threading.Event()
        self.cmd: socket.socket | None = None
        self.stream: socket.socket | None = None
        self.cmd_buf = bytearray()
        self.stream_done = threading.Event()  # stop sending poses
        self.stream_threads: list[threading.Thread] = []
        self.cycle_t0: float | None = None
        self.lock = threading.Lock()

    # -- the session -------------------------------------------------------------------------
    def run(self) -> Outcome:
        c = self.c
        try:
            self.cmd = self._connect()
            self._extras("start")
            if c.session == "E4":
                ans = self._command(wire.PROG_IDX, [c.program_index])
                if ans.value == 409:
                    raise SessionStop(3, "ProgIdx answered 409: box not ready")
            if c.session == "cycle-on-first":
                self._cycle_on()
                self._stream_on()
                self._wait(c.duration)
                self._cycle_off()
            else:
                self._stream_on()
                self._extras("stream on")
                if c.no_wait:
                    self._cycle_without_waiting()
                    self._wait(c.duration)
                for k in range(0 if c.no_wait else int(c.cycles)):
                    self._cycle_on()
                    self._extras("in-cycle" if k == 0 else "")
                    self._wait(c.duration / int(c.cycles))
                    self._cycle_off()
                    self._extras("after-cycle" if k == 0 else "")
            self._stream_off()
            if c.session == "E4":
                self._wait(1.0)
                self._vision_result()
            self._close(self.cmd)
            if c.leave_stream_open:
                self._hold_stream()
        except SessionStop as stop:
            self.outcome.exit_code, self.outcome.reason = stop.code, stop.reason
        except OSError as exc:
            self.outcome.exit_code, self.outcome.reason = 5, f"connection failed: {exc.strerror or exc}"
        finally:
            self.stream_done.set()
            for thread in self.stream_threads:
                thread.join(c.time_out + 1)
            self._close(self.cmd)
            self._close(self.stream)
        if self.outcome.exit_code == 0 and self.outcome.problems:
            self.outcome.exit_code, self.outcome.reason = 1, f"{self.outcome.problems} answer(s) not 0000"
        return self.outcome

    def stop(self) -> None:
        self.stopping.set()

    def _wait(self, seconds: float) -> None:
        if self.stopping.wait(seconds):
            raise SessionStop(1, "stopped")

    def _connect(self) -> socket.socket:
        sock = socket.create_connection(self.target, timeout=self.c.time_out)
        sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        return sock

    @staticmethod
    def _close(sock: socket.socket | None) -> None:
        """Close now: shutdown first, or a reader blocked in recv() would hold the FIN back."""
        if sock is not None:
            with contextlib.suppress(OSError):
                sock.shutdown(socket.SHUT_RDWR)
            with contextlib.suppress(OSError):
                sock.close()

    def _encode(self, action: int, blocks: list) -> bytes:  # type: ignore[type-arg]
        c = self.c
        return encode_request(action, blocks, transfer=c.transfer, first_index=c.first_index, float_order=c.float_order)

    # -- the command connection: lock-step ------------------------------------------------------
    def _command(self, action: int, blocks: list | None = None, bound: float | None = None) -> Answer:  # type: ignore[type-arg]
        assert self.cmd is not None
        self._send(self.cmd, self._encode(action, blocks or []))
        self.outcome.commands += 1
        bound = self.c.time_out if bound is None else bound
        deadline = time.monotonic() + bound
        while True:
            try:
                answers = split_answers(self.cmd_buf)
            except ValueError as exc:
                raise SessionStop(1, f"garbage on the command connection: {exc}") from None
            if answers:
                ans = answers[0]
                if ans.action != action:
                    raise SessionStop(1, f"action {action:02X} answered with action {ans.action:02X}")
                if ans.error != wire.OK:
                    self.outcome.problems += 1
                return ans
            self._read_command(deadline, f"no answer to action {action:02X} within {bound:g} s",
                               f"action {action:02X}")

    def _read_command(self, deadline: float, late: str, waiting_for: str) -> None:
        """Read what has come on the command connection (at most 0.2 s) into ``cmd_buf``; past ``deadline`` or
        when stopping, SessionStop 4 with ``late``; on a close, SessionStop 5."""
        assert self.cmd is not None
        left = deadline - time.monotonic()
        if left <= 0 or self.stopping.is_set():
            raise SessionStop(4, late)
        self.cmd.settimeout(min(left, 0.2))
        try:
            data = self.cmd.recv(4096)
        except TimeoutError:
            return
        if not data:
            raise SessionStop(5, f"the box closed the command connection (waiting for {waiting_for})")
        self.cmd_buf += data

    def _cycle_without_waiting(self) -> None:
        """The planted A1 defect: CycleOn, CycleOff 1 ms later without waiting for CycleOn's answer, then both answers
        (a box that answers in under a millisecond hides it; one that takes time to start a detection shows it)."""
        assert self.cmd is not None
        self._send(self.cmd, self._encode(wire.CYCLE_ON, []))
        time.sleep(0.001)
        self._send(self.cmd, self._encode(wire.CYCLE_OFF, []))
        self.outcome.commands += 2
        deadline = time.monotonic() + self.c.time_out
        got: list[Answer] = []
        while True:
            try:
                got += split_answers(self.cmd_buf)
            except ValueError as exc:
                raise SessionStop(1, f"garbage on the command connection: {exc}") from None
            if len(got) >= 2:
                break
            self._read_command(deadline, f"{len(got)} of the answers to CycleOn and CycleOff within {self.c.time_out:g} s",
                               "CycleOn and CycleOff")
        self.outcome.problems += sum(1 for a in got if a.error != wire.OK)

    def _extras(self, when: str) -> None:
        """The legal requests between the session's steps: pings, poses on the command connection, tolerances."""
        c = self.c
        if when == "start" and c.pings != "0" or when in ("stream on", "in-cycle") and c.pings == "3":
            self._command(wire.NONE)
        if c.tolerance_at == when:
            self._command(wire.TOLERANCE, [0.5 + 0.25 * i for i in range(int(c.tolerance_blocks))])
        if when == "stream on" and c.cmd_poses in ("pose", "both"):
            self._command(wire.POSE, [self._pose(time.perf_counter())])  # ISIGHT(3,35): the TP pose
        if when == "stream on" and c.cmd_poses in ("register", "both"):
            self._command(wire.REG_POSE, [HOME])  # ISIGHT(3,36,PR_ID)

    def _cycle_off(self) -> None:
        self._command(wire.CYCLE_OFF)
        self.cycle_t0 = None

    def _send(self, sock: socket.socket, data: bytes) -> None:
        """Write one request the robot's way (whole, in two pieces, or a byte per send)."""
        if self.c.writer == "whole":
            sock.sendall(data)
        elif self.c.writer == "pieces":
            sock.sendall(data[:12])
            time.sleep(PIECE_PAUSE)
            sock.sendall(data[12:])
        else:
            for i in range(len(data)):
                sock.sendall(data[i : i + 1])

    def _cycle_on(self) -> None:
        ans = self._command(wire.CYCLE_ON)
        if ans.error == wire.NOT_READY:
            raise SessionStop(3, "CycleOn answered 0001: box not ready")
        self.cycle_t0 = time.perf_counter()

    def _vision_result(self) -> None:
        for _ in range(5):
            ans = self._command(wire.RESULT, bound=self.c.vision_time_out)
            if ans.value != 202:
                return
            self._wait(0.5)

    # -- the stream connection --------------------------------------------------------------------
    def _pose(self, now: float) -> tuple[float, ...]:
        if self.cycle_t0 is None:
            return HOME
        t = now - self.cycle_t0
        return (800.0 + 100.0 * math.sin(t), 50.0 * t, 500.0 - 20.0 * t, 180.0, 0.0, 10.0 * math.sin(t))

    def _stream_on(self) -> None:
        self.stream = self._connect()
        for target in (self._send_poses, self._read_answers):
            thread = threading.Thread(target=target, name=f"robot-{target.__name__}", daemon=True)
            thread.start()
            self.stream_threads.append(thread)
        if self.c.read_late != "late":  # Send_Pos_On returns once the first pose is answered
            deadline = time.monotonic() + self.c.time_out
            while self.outcome.poses_answered == 0 and time.monotonic() < deadline and not self.stopping.is_set():
                time.sleep(0.01)
        else:
            self._wait(0.3)

    def _send_poses(self) -> None:
        stream, c = self.stream, self.c
        assert stream is not None
        period = 1.0 / (c.rate_hz * c.rate_factor)
        due = time.perf_counter()
        nan_at = int(c.rate_hz * c.rate_factor * c.duration / 2) if c.nan_pose else -1
        sent = 0
        while not self.stream_done.is_set() and not self.stopping.is_set():
            now = time.perf_counter()
            if now < due - SPIN:
                time.sleep(due - now - SPIN)
                continue
            while now < due:  # the last SPIN seconds spin: a controller's clock does not oversleep
                now = time.perf_counter()
            pose = self._pose(now)
            if self.cycle_t0 is not None and nan_at >= 0:
                nan_at -= 1
                if nan_at == 0:
                    pose = (math.nan, *pose[1:])
            try:
                self._send(stream, self._encode(wire.POSE, [pose]))
            except OSError:
                return
            sent += 1
            with self.lock:
                self.outcome.poses_sent = sent
            due += period
            if due < now:  # more than a period late (a loaded machine): skip ahead rather than burst
                due = now + period

    def _read_answers(self) -> None:
        stream = self.stream
        assert stream is not None
        buf = bytearray()
        stream.settimeout(0.2)
        while not self.stopping.is_set():
            if self.c.read_late == "late" and self.stopping.wait(0.5):
                return
            try:
                data = stream.recv(65536)
            except TimeoutError:
                if self.stream_done.is_set() and self.outcome.poses_answered >= self.outcome.poses_sent:
                    return
                continue
            except OSError:
                return
            if not data:
                return
            buf += data
            try:
                answers = split_answers(buf)
            except ValueError:
                self.outcome.problems += 1
                return
            for ans in answers:
                self.outcome.poses_answered += 1
                if ans.action != wire.POSE or ans.error != wire.OK:
                    self.outcome.problems += 1

    def _stream_off(self) -> None:
        """Send_Pos_Off: stop the poses, wait (up to time_out) for their answers, close."""
        self.stream_done.set()
        self.stream_threads[0].join(self.c.time_out)
        deadline = time.monotonic() + self.c.time_out
        while self.outcome.poses_answered < self.outcome.poses_sent and time.monotonic() < deadline:
            if self.stopping.wait(0.02):
                break
        if not self.c.leave_stream_open:
            self._close(self.stream)

    def _hold_stream(self) -> None:
        """The planted S5 defect: keep the stream open until the box closes it (at most 30 s)."""
        stream = self.stream
        assert stream is not None
        deadline = time.monotonic() + 30
        self.stream_threads[1].join(30)  # the reader ends once every pose is answered
        stream.settimeout(0.2)
        while time.monotonic() < deadline and not self.stopping.is_set():
            try:
                if not stream.recv(4096):
                    return
            except TimeoutError:
                continue
            except OSError:
                return

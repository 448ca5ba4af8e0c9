"""One robot session of the soak: the canonical session (S1, E4 with the extension) of
:class:`~conformance.endpoints.robot.RobotSession`, with a planted event when one is due.

* ``vanish``: mid-cycle the robot is power-cycled: the poses stop, and both connections are
  abandoned without FIN or RST. Their sockets are kept open in the :class:`Ghosts` ring (a
  duplicate of each descriptor, so that closing asyncio's transport sends nothing), and the
  robot's next session, the rebooted robot, connects from new ports and must be served;
* ``reset``: mid-cycle both connections are reset (SO_LINGER 0, then closed: an RST);
* ``stall``: mid-cycle the stream stops for ``stall_s`` seconds, then resumes; every pose is
  still answered within time_out;
* ``burst``: :func:`reconnect_burst`, many connections at once, each a ping.

What a session leaves the soak is a :class:`~.windows.SessionOutcome`; its timeline is dropped.
"""

from __future__ import annotations

import asyncio
import contextlib
import dataclasses
import os
import socket
import struct
import time
from collections import deque
from dataclasses import dataclass
from typing import Any

from ..endpoints.robot import RobotSession
from ..endpoints.robot.robot_io import Link, Stop
from ..endpoints.robot.robot_result import EXIT_CONNECTION, EXIT_MISBEHAVED, EXIT_NOT_READY, EXIT_OK, EXIT_TIMEOUT
from ..endpoints.robot.robot_steps import Judge, Judgement
from ..protocol import Action, ErrorCode, Frame, Profile, ResultCode, StreamDecoder, TransferType, codec_for, request
from .windows import SessionOutcome

perf = time.perf_counter
#: the exit code of a session ended on purpose by a planted vanish or reset
EXIT_PLANTED = -1
LINGER_RST = struct.pack("ii", 1, 0)


@dataclass
class Ghost:
    """An abandoned connection: the robot that held it is gone, the box does not know."""

    sock: socket.socket
    port: int  # the robot side's port: the box sees it as the peer's
    since: float
    freed_after_s: float | None = None  # the box closed it itself after this long


class Ghosts:
    """The half-open connections the soak keeps open: at most ``most``, each for ``hold_s``; then it
    is released with an RST, as the rebooted robot's stack answers the box's next segment."""

    def __init__(self, hold_s: float, most: int = 256) -> None:
        self.hold_s = hold_s
        self.most = most
        self.ring: deque[Ghost] = deque()
        self.abandoned = self.freed_by_box = self.released = 0
        self.freed_after: list[float] = []  # bounded: the last 100

    def keep(self, link: Link | None) -> None:
        transport = link.transport if link is not None else None
        if transport is None or transport.is_closing():
            return
        raw = transport.get_extra_info("socket")
        if raw is None:
            return
        try:
            sock = socket.socket(fileno=os.dup(raw.fileno()))
            port = sock.getsockname()[1]
        except OSError:
            return
        transport.abort()  # asyncio closes its descriptor; the duplicate keeps the connection open, silent
        self.ring.append(Ghost(sock, port, perf()))
        self.abandoned += 1
        while len(self.ring) > self.most:
            self._release(self.ring.popleft())

    def _release(self, ghost: Ghost) -> None:
        with contextlib.suppress(OSError):
            ghost.sock.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, LINGER_RST)
        ghost.sock.close()
        self.released += 1

    def sweep(self, now: float | None = None) -> None:
        """Note the ghosts the box closed, release those held ``hold_s``."""
        now = perf() if now is None else now
        kept: deque[Ghost] = deque()
        for ghost in self.ring:
            if ghost.freed_after_s is None and self._closed_by_box(ghost.sock):
                ghost.freed_after_s = now - ghost.since
                self.freed_by_box += 1
                self.freed_after = [*self.freed_after[-99:], ghost.freed_after_s]
            if now - ghost.since >= self.hold_s or ghost.freed_after_s is not None:
                self._release(ghost)
            else:
                kept.append(ghost)
        self.ring = kept

    @staticmethod
    def _closed_by_box(sock: socket.socket) -> bool:
        try:
            return sock.recv(1, socket.MSG_PEEK | socket.MSG_DONTWAIT) == b""
        except BlockingIOError:
            return False  # open, nothing sent: the usual half-open connection
        except OSError:
            return True  # reset by the box

    def ports(self) -> set[int]:
        return {g.port for g in self.ring}

    def release_all(self) -> None:
        while self.ring:
            self._release(self.ring.popleft())

    def to_dict(self) -> dict[str, Any]:
        freed = sorted(self.freed_after)
        return {"abandoned": self.abandoned, "held_now": len(self.ring), "freed_by_box": self.freed_by_box,
                "released_by_rst": self.released, "hold_s": self.hold_s,
                "freed_after_s_median": freed[len(freed) // 2] if freed else None}


class SoakSession(RobotSession):
    """The canonical session with one planted event (or none); ``outcome()`` after ``run()``."""

    def __init__(self, target: tuple[str, int], profile: Profile, *, robot: int, duration: float, extension: bool,
                 event: str = "", event_at: float = 0.5, stall_s: float = 0.0, after_event: str = "",
                 ghosts: Ghosts | None = None, result_wait: float = 1.0, shared: bool = False,
                 clear_cycle: bool = False) -> None:
        super().__init__(target, profile, duration=duration, extension=extension, result_wait=result_wait)
        self.shared = shared  # other robots play on the same box at once: its cycle may be theirs (S3)
        #: a CycleOff first: the robot's last cycle was left open (it vanished, was reset, or was told not ready)
        self.clear_cycle = clear_cycle
        self.robot = robot
        self.event = event
        self.event_at = event_at
        self.stall_s = stall_s
        self.after_event = after_event
        self.ghosts = ghosts
        self.connect_ms: list[float] = []
        self.phase = ""  # "connect" or "command-starved" when that is where it failed

    async def _connect(self, name: str, address: tuple[str, int], on_event: Any) -> Link:
        t = perf()
        try:
            link = await super()._connect(name, address, on_event)
        except Stop:
            self.phase = "connect"
            raise
        self.connect_ms.append((perf() - t) * 1000.0)
        return link

    async def _command(self, action: Action, blocks: tuple = (), timeout: float | None = None,
                       bound: str = "time_out") -> Any:
        try:
            return await super()._command(action, blocks, timeout, bound)
        except Stop as stop:
            stream = self._stream
            if stop.code == EXIT_TIMEOUT and stream is not None and not stream.eof and self.result.poses_answered:
                self.phase = "command-starved"  # the stream was served, the command was not (S4)
            raise

    async def _io_connect(self, step: Any) -> None:
        await super()._io_connect(step)
        if self.clear_cycle:  # like a rebooted cell: end a cycle left open; 0000 or 0002 (idle) are both fine (S3)
            await self._command(Action.CYCLE_OFF)

    async def _io_command(self, step: Any) -> None:
        if self.shared and step.action is Action.CYCLE_OFF and step.judge is not None:
            step = dataclasses.replace(step, judge=_shared_cycle_off(step.judge))
        await super()._io_command(step)

    async def _io_trajectory(self, step: Any) -> None:
        if self.event not in ("vanish", "reset", "stall"):
            await super()._io_trajectory(step)
            return
        if self._cycle_start is None:
            self._cycle_start = perf()
        first = self.duration * self.event_at
        await self._sleep(first)
        if self.event == "stall":
            await self._stop_sender()
            await self._sleep(self.stall_s)
            self._check_failure()
            self._stop_poses = False
            self._sender = asyncio.get_running_loop().create_task(self._pose_loop())
            await self._sleep(self.duration - first)
            return
        await self._stop_sender()
        if self.event == "vanish" and self.ghosts is not None:
            self.ghosts.keep(self._cmd)
            self.ghosts.keep(self._stream)
        else:
            for link in (self._cmd, self._stream):
                _reset(link)
        self._cmd = self._stream = None
        raise Stop(EXIT_PLANTED, f"planted: the robot {'vanished' if self.event == 'vanish' else 'reset'} mid-cycle")

    async def _stop_sender(self) -> None:
        self._stop_poses = True
        if self._sender is not None:
            with contextlib.suppress(Stop, asyncio.CancelledError):
                await self._sender
            self._sender = None

    def outcome(self, time_out_ms: float) -> SessionOutcome:
        result = self.result
        failure = classify(result.exit_code, self.phase, self.after_event)
        latencies = result.pose_latencies_ms
        return SessionOutcome(
            self.robot, not failure, failure, result.reason if failure else "", self.event, self.after_event,
            result.poses_sent, result.poses_answered, latencies, list(result.command_latencies_ms.values()),
            self.connect_ms, sum(1 for v in latencies if v > time_out_ms),
            prog_idx_conflict=result.prog_idx_answer == ResultCode.CONFLICT,
        )


def _shared_cycle_off(judge: Judge) -> Judge:
    """CycleOff's judge when several robots share the box: 0002 is allowed, the box-wide cycle may have been
    ended by another robot's CycleOff (S3: cycle state per box, CycleOff when idle answered 0000 or an error)."""
    def shared(frame: Frame, program_index: int) -> Judgement:
        if frame.error_code == ErrorCode.CYCLE_OFF_FAILED:
            return Judgement(reason="CycleOff answered 0002: the box's cycle was ended by another robot (S3)")
        return judge(frame, program_index)

    return shared


def classify(code: int, phase: str, after_event: str) -> str:
    """What ended a session: "" (served whole, or ended on purpose), else a failure kind of
    :data:`~.windows.FAILURE_CLAUSE` or "not-ready"."""
    if code in (EXIT_OK, EXIT_PLANTED):
        return ""
    if code == EXIT_NOT_READY:
        return "not-ready"
    if code == EXIT_MISBEHAVED:
        return "misbehaved"
    failure = phase or ("timeout" if code == EXIT_TIMEOUT else "closed" if code == EXIT_CONNECTION else "misbehaved")
    if after_event == "vanish" and failure in ("connect", "closed", "timeout"):
        return "after-vanish"  # the rebooted robot was not served (R5)
    return failure


def _reset(link: Link | None) -> None:
    transport = link.transport if link is not None else None
    if transport is None or transport.is_closing():
        return
    raw = transport.get_extra_info("socket")
    if raw is not None:
        with contextlib.suppress(OSError):
            raw.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, LINGER_RST)
    transport.abort()


Ping = tuple[float | None, float | None, str, str]


async def _ping_once(target: tuple[str, int], profile: Profile, time_out: float) -> Ping:
    """(connect ms, answer ms, failure kind, why) of one connection of a burst: connect, ping (00), close."""
    t = perf()
    try:
        reader, writer = await asyncio.wait_for(asyncio.open_connection(*target), time_out)
    except (OSError, asyncio.TimeoutError) as exc:
        return None, None, "connect", f"burst connection not accepted within time_out: {exc.__class__.__name__} {exc}"
    connect_ms = (perf() - t) * 1000.0
    decoder = StreamDecoder(profile, TransferType.BOX_TO_ROBOT)
    try:
        sent = perf()
        writer.write(codec_for(profile).encode(request(Action.NONE)))
        deadline = sent + time_out
        while True:
            remaining = deadline - perf()
            if remaining <= 0:
                return connect_ms, None, "timeout", "burst ping not answered within time_out (T1)"
            data = await asyncio.wait_for(reader.read(4096), remaining)
            if not data:
                return connect_ms, None, "closed", "the box closed a burst connection before answering its ping"
            decoder.receive_data(data)
            events = list(decoder.events())
            if events:
                if not isinstance(events[0], Frame) or events[0].action is not Action.NONE:
                    return connect_ms, None, "misbehaved", f"burst ping answered with {events[0]} (A4)"
                return connect_ms, (perf() - sent) * 1000.0, "", ""
    except (OSError, asyncio.TimeoutError):
        return connect_ms, None, "timeout", "burst ping not answered within time_out (T1)"
    finally:
        writer.close()
        with contextlib.suppress(Exception):
            await asyncio.wait_for(writer.wait_closed(), 1.0)


async def reconnect_burst(target: tuple[str, int], profile: Profile, robot: int, size: int) -> SessionOutcome:
    """``size`` connections at once, each a ping: all must be accepted and answered within time_out."""
    time_out = profile.time_out_s
    results = await asyncio.gather(*(_ping_once(target, profile, time_out) for _ in range(size)))
    failures = [(kind, why) for _, _, kind, why in results if kind]
    outcome = SessionOutcome(robot, not failures, "", "", "burst")
    outcome.connect_ms = [c for c, _, _, _ in results if c is not None]
    outcome.command_latencies_ms = [a for _, a, _, _ in results if a is not None]
    if failures:
        kinds = {kind for kind, _ in failures}
        outcome.failure = next(k for k in ("connect", "closed", "timeout", "misbehaved") if k in kinds)
        outcome.reason = f"{len(failures)} of {size} burst connections failed: {failures[0][1]}"
    return outcome


__all__ = ["EXIT_PLANTED", "Ghost", "Ghosts", "SoakSession", "classify", "reconnect_burst"]

"""The robot simulator over asyncio: plays a session (S1, or E4 with the extension; the steps
and what they expect are :mod:`.robot_steps`) like the KAREL programs ``ISIGHT`` and
``Send_Pos_On``/``Send_Pos_Off`` do.

The command connection is synchronous (send, wait for the answer up to
``time_out``); the stream connection sends on a fixed clock and matches answers
as they come (S6). Library use::

    result = await RobotSession(("127.0.0.1", 9004), profile, duration=2.0).run()
    result.ok, result.exit_code, result.reason, result.timeline

:class:`~.robot_steps.RobotFaults` makes deliberately broken robots (little-endian floats,
indexes from 1, a wrong block length, bursty or drifting streams, a stream left
open, frames sent in pieces, any byte-level change through ``encode_hook``), and
``steps`` replaces the session's order. Every outcome is a :class:`~.robot_result.RobotResult`
with an exit code and a one-line reason: never a traceback.
"""

from __future__ import annotations

import asyncio
import time
from collections import deque
from collections.abc import Awaitable, Callable, Sequence

from ...harness.target import Target
from ...harness.trajectory import Pose, PrimerTrajectory
from ...protocol import (
    DEFAULT_PORT,
    DEFAULT_PROFILE,
    Action,
    Frame,
    Profile,
    ProtocolError,
    pose_blocks,
    request,
    value_blocks,
)
from ..loop import run_loop
from .robot_io import SessionIO, Stop
from .robot_result import (
    EXIT_CONNECTION,
    EXIT_MISBEHAVED,
    EXIT_OK,
    EXIT_TIMEOUT,
    RobotResult,
    TimelineEntry,
    frame_text,
    pose_text,
)
from .robot_steps import (
    STEP_TABLE,
    Io,
    RobotFaults,
    Step,
    answer_value,
    judge_answer,
    judge_malformed,
    judge_pose,
    session_steps,
)

perf = time.perf_counter


def parse_target(text: str, default_port: int = DEFAULT_PORT) -> tuple[str, int]:
    """``HOST:PORT``, ``[V6]:PORT`` or ``HOST`` → (host, port); ValueError if malformed."""
    target = Target.parse(text, default_port)
    return target.host, target.port


class RobotSession(SessionIO):
    """One robot session against a box; ``await session.run()`` → :class:`RobotResult`."""

    def __init__(
        self,
        target: tuple[str, int] | str,
        profile: Profile = DEFAULT_PROFILE,
        *,
        stream_target: tuple[str, int] | str | None = None,
        duration: float = 2.0,
        extension: bool = False,
        ping: bool = False,
        program_index: int = 1,
        result_wait: float = 1.0,
        trajectory: PrimerTrajectory | None = None,
        faults: RobotFaults | None = None,
        steps: Sequence[str] | None = None,
        stop_on_error: bool = True,
    ) -> None:
        self.target: tuple[str, int] = parse_target(target) if isinstance(target, str) else (target[0], int(target[1]))
        st = stream_target if stream_target is not None else self.target
        self.stream_target: tuple[str, int] = parse_target(st) if isinstance(st, str) else (st[0], int(st[1]))
        if not 0 < duration <= 3600:
            raise ValueError("duration must be in (0, 3600] seconds")
        if not 0 <= result_wait <= 60:
            raise ValueError("result wait must be in [0, 60] seconds")
        if not -(2**31) <= program_index < 2**31:
            raise ValueError("program index must fit a signed int32 (E1)")
        self.duration = duration
        self.extension = extension
        self.program_index = program_index
        self.result_wait = result_wait
        self.trajectory = trajectory or PrimerTrajectory(duration=duration)
        super().__init__(profile, faults or RobotFaults(), session_steps(extension, ping, steps), stop_on_error)
        self._cmd_events: deque[tuple[float, Frame | ProtocolError]] = deque()
        self._outstanding: deque[tuple[int, float, TimelineEntry]] = deque()
        self._cycle_start: float | None = None
        self._cycle_end: float | None = None
        self._last_send = 0.0
        #: what the driver does for each kind of step (the steps themselves: robot_steps.STEP_TABLE)
        self._io: dict[Io, Callable[[Step], Awaitable[None]]] = {
            Io.CONNECT: self._io_connect, Io.COMMAND: self._io_command, Io.STREAM_ON: self._io_stream_on,
            Io.TRAJECTORY: self._io_trajectory, Io.STREAM_OFF: self._io_stream_off, Io.WAIT: self._io_wait,
            Io.DISCONNECT: self._io_disconnect,
        }

    # -- running ---------------------------------------------------------------------------------
    async def run(self) -> RobotResult:
        """Play the session; never raises for anything the box or the network does."""
        self._t0 = perf()
        result = self.result
        try:
            for name in self.steps:
                step = STEP_TABLE[name]
                await self._io[step.io](step)
                if self._failure is not None:
                    raise self._failure
        except Stop as stop:
            result.exit_code, result.reason = stop.code, stop.reason
        except OSError as exc:  # anything the socket layer throws at us
            result.exit_code, result.reason = EXIT_CONNECTION, f"network error: {exc}"
        finally:
            await self._teardown()
            result.duration_ms = self._ms(perf())
        if result.exit_code == EXIT_OK and result.problems:
            result.exit_code, result.reason = result.problems[0]
        return result

    # -- the command connection ----------------------------------------------------------------------
    def _on_cmd_event(self, now: float, event: Frame | ProtocolError) -> None:
        self._cmd_events.append((now, event))

    async def _command(self, action: Action, blocks: tuple = (), timeout: float | None = None,
                       bound: str = "time_out") -> tuple[Frame | None, TimelineEntry]:
        link = self._cmd
        if link is None or link.lost:
            self._problem(EXIT_CONNECTION, f"{action.name}: the command connection is not open", fatal=True)
        assert link is not None
        if self._cmd_events:
            _, extra = self._cmd_events.popleft()
            what = extra.describe() if isinstance(extra, Frame) else str(extra)
            self._problem(EXIT_MISBEHAVED, f"unsolicited frame on the command connection before {action.name}: {what} (A1)")
        frame = request(action, blocks)
        data = self._encode(frame)
        t_sent = perf()
        entry = self._note("cmd", "-> " + frame_text(frame), t_sent)
        link.write(data, self.faults.segment_size)
        timeout = self.time_out if timeout is None else timeout

        def expired() -> None:
            ms = round(timeout * 1000)
            clause = "E3/E5" if action is Action.VISION_RESULT else "T1"
            self._problem(EXIT_TIMEOUT, f"no answer to {action.name} within {bound} {ms} ms ({clause})", entry, fatal=True)

        def closed_or_answered() -> bool:
            return bool(self._cmd_events) or link.eof

        await self._until(closed_or_answered, timeout, expired)
        if not self._cmd_events:
            self._problem(EXIT_CONNECTION, f"the box closed the command connection while {action.name} waited for "
                          "its answer", entry, fatal=True)
        t_ans, event = self._cmd_events.popleft()
        entry.latency_ms = (t_ans - t_sent) * 1000.0
        self.result.command_latencies_ms[action.name] = entry.latency_ms
        if isinstance(event, ProtocolError):
            entry.answer = f"malformed answer [{event.clause}]"
            self._judge(judge_malformed(action.name, event), entry)
            return None, entry
        entry.answer = frame_text(event)
        judgement = judge_answer(action, event)
        if judgement.code != EXIT_OK:
            self._judge(judgement, entry)
            return None, entry
        return event, entry

    # -- the steps' I/O (which step does what, and its judges: robot_steps.STEP_TABLE) --------------------
    async def _io_connect(self, step: Step) -> None:
        self._cmd = await self._connect("cmd", self.target, self._on_cmd_event)

    async def _io_command(self, step: Step) -> None:
        assert step.action is not None and step.judge is not None
        blocks = value_blocks([self.program_index], self._first_index) if step.carries_index else ()
        timeout = self.vision_time_out if step.bound == "vision_time_out" else self.time_out
        frame, entry = await self._command(step.action, blocks, timeout=timeout, bound=step.bound)
        if step.cycle == "end":
            self._cycle_end = perf()
        if frame is not None:
            if step.keep is not None:
                step.keep(self.result, answer_value(frame))
            self._judge(step.judge(frame, self.program_index), entry)
        if step.cycle == "start":
            self._cycle_start = perf()

    async def _io_stream_on(self, step: Step) -> None:
        stream = self._stream = await self._connect("stream", self.stream_target, self._on_stream_event)
        self._stop_poses = False
        self._sender = asyncio.get_running_loop().create_task(self._pose_loop())

        def expired() -> None:
            entry = self._outstanding[0][2] if self._outstanding else None
            self._problem(EXIT_TIMEOUT, f"first pose not answered within time_out {self.profile.time_out_ms} ms (T1)",
                          entry)

        # like Send_Pos_On, return once the stream flows: the first pose has its answer
        await self._until(lambda: self.result.poses_answered > 0 or bool(self.result.problems) or stream.eof,
                          self.time_out, expired)

    async def _io_trajectory(self, step: Step) -> None:
        if self._cycle_start is None:
            self._cycle_start = perf()
        self._note("-", f"primer trajectory, {self.duration:g} s")
        await self._sleep(self.duration)

    async def _io_stream_off(self, step: Step) -> None:
        self._stop_poses = True
        if self._sender is not None:
            await self._sender
            self._sender = None
        self._check_failure()
        stream = self._stream
        if stream is None:
            return

        def expired() -> None:
            seq = self._outstanding[0][0]
            self._problem(EXIT_TIMEOUT, f"{len(self._outstanding)} pose(s) from #{seq} on not answered within "
                          f"time_out {self.profile.time_out_ms} ms (T1)", self._outstanding[0][2])

        wait = max(0.0, self._last_send + self.time_out - perf())
        await self._until(lambda: not self._outstanding or stream.eof, wait, expired)
        if self._outstanding:
            self._problem(EXIT_CONNECTION, f"the box closed the stream connection with {len(self._outstanding)} "
                          "pose(s) unanswered", self._outstanding[0][2])
        if self.faults.leave_stream_open:
            self._note("stream", "Send_Pos_Off: poses stopped, connection left open (fault)")
            return
        stream.close()
        self._note("stream", "Send_Pos_Off: closed")

    async def _io_wait(self, step: Step) -> None:
        await self._sleep(self.result_wait)

    async def _io_disconnect(self, step: Step) -> None:
        link = self._cmd
        if link is not None:
            if self._cmd_events:
                _, extra = self._cmd_events.popleft()
                what = extra.describe() if isinstance(extra, Frame) else str(extra)
                self._problem(EXIT_MISBEHAVED, f"unsolicited frame on the command connection: {what} (A1)")
            link.close()
            self._note("cmd", "disconnected")

    # -- the stream connection ---------------------------------------------------------------------------
    def _pose_now(self, now: float) -> Pose:
        trajectory = self.trajectory
        if self._cycle_start is None or now < self._cycle_start:
            return trajectory.home
        if self._cycle_end is not None:
            return trajectory.pose_at(trajectory.duration)
        return trajectory.pose_at(now - self._cycle_start)

    async def _pose_loop(self) -> None:
        stream = self._stream
        assert stream is not None
        faults = self.faults
        period = self.period
        result = self.result
        t_start = next_due = perf()
        seq = 0
        previous = None
        try:
            while not self._stop_poses:
                now = perf()
                if now < next_due:
                    await asyncio.sleep(next_due - now)
                    continue
                for _ in range(faults.burst):
                    now = perf()
                    frame = request(Action.POSE, pose_blocks([self._pose_now(now)], self._first_index))
                    data = self._encode(frame)
                    entry = TimelineEntry(self._ms(now), "stream", f"-> POSE #{seq} {pose_text(frame)}")
                    result.timeline.append(entry)
                    self._outstanding.append((seq, now, entry))
                    stream.write(data, faults.segment_size)
                    if previous is not None:
                        result.send_intervals_ms.append((now - previous) * 1000.0)
                    previous = self._last_send = now
                    result.poses_sent += 1
                    seq += 1
                next_due += faults.burst * period * (1.0 + faults.drift * (now - t_start))
                if self._outstanding and now - self._outstanding[0][1] > self.time_out:
                    first = self._outstanding[0]
                    self._problem(EXIT_TIMEOUT, f"pose #{first[0]} not answered within time_out "
                                  f"{self.profile.time_out_ms} ms (T1)", first[2])
                if stream.eof and not stream.closing:
                    self._problem(EXIT_CONNECTION, "the box closed the stream connection during Send_Pos_On")
        except Stop as stop:  # recorded by _problem, or a write to a closed stream
            if self._failure is None:
                self.result.problems.append((stop.code, stop.reason))
                self._failure = stop
                self._wake.set()

    def _on_stream_event(self, now: float, event: Frame | ProtocolError) -> None:
        try:
            if not self._outstanding:
                what = event.describe() if isinstance(event, Frame) else str(event)
                self._problem(EXIT_MISBEHAVED, f"unsolicited frame on the stream connection: {what} (A1)")
                return
            seq, t_sent, entry = self._outstanding.popleft()
            entry.latency_ms = latency = (now - t_sent) * 1000.0
            if isinstance(event, ProtocolError):
                entry.answer = f"malformed answer [{event.clause}]"
                self._judge(judge_malformed(f"pose #{seq}", event), entry)
                return
            entry.answer = frame_text(event)
            self.result.poses_answered += 1
            self.result.pose_latencies_ms.append(latency)
            self._judge(judge_pose(seq, event), entry)
        except Stop:
            pass  # recorded in self._failure; the main flow ends the session


def run_robot(session: RobotSession, loop: str = "asyncio") -> RobotResult:
    """Run a session to completion from synchronous code."""
    return run_loop(session.run(), loop)


__all__ = ["RobotSession", "parse_target", "run_robot"]

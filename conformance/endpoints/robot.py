"""The robot simulator: plays the canonical session (S1, or E4 with the extension) like
the KAREL programs ``ISIGHT`` and ``Send_Pos_On``/``Send_Pos_Off`` do.

S1: connect the command connection → ``Send_Pos_On`` (stream connection, poses at
the stream rate) → CycleOn → primer trajectory (``duration`` s) → CycleOff →
``Send_Pos_Off`` (poses stop, the stream closes) → disconnect.

E4: connect → ProgIdx (26) → ``Send_Pos_On`` → CycleOn → trajectory → CycleOff →
``Send_Pos_Off`` → wait 1 s → result request (27, bounded by ``vision_time_out``)
→ disconnect.

The command connection is synchronous (send, wait for the answer up to
``time_out``); the stream connection sends on a fixed clock and matches answers
as they come (S6). Library use::

    result = await RobotSession(("127.0.0.1", 9004), profile, duration=2.0).run()
    result.ok, result.exit_code, result.reason, result.timeline

:class:`RobotFaults` makes deliberately broken robots (little-endian floats,
indexes from 1, a wrong block length, bursty or drifting streams, a stream left
open, frames sent in pieces, any byte-level change through ``encode_hook``), and
``steps`` replaces the session's order. Every outcome is a :class:`RobotResult`
with an exit code and a one-line reason: never a traceback.
"""

from __future__ import annotations

import asyncio
import contextlib
import math
import statistics
import time
from collections import deque
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

from ..harness.target import Target
from ..protocol import (
    DEFAULT_PORT,
    DEFAULT_PROFILE,
    Action,
    ErrorCode,
    Frame,
    Profile,
    ProtocolError,
    ResultCode,
    StreamDecoder,
    TransferType,
    codec_for,
    pose_blocks,
    request,
    value_blocks,
)
from ..protocol.answers import SENDABLE_RESULTS
from ..protocol.frames import ValueBlock
from ..stats import percentile
from ..trajectory import Pose, PrimerTrajectory

EXIT_OK = 0
EXIT_MISBEHAVED = 1  # the box broke the protocol (wrong code, action, malformed answer, ...)
EXIT_NOT_READY = 3  # CycleOn answered 0001 / ProgIdx answered 409: the cycle is inconclusive (S2)
EXIT_TIMEOUT = 4  # no answer within time_out / vision_time_out (T1, E3)
EXIT_CONNECTION = 5  # connection refused, failed or closed by the box

#: The canonical sessions as data: each name is a step of :class:`RobotSession`.
S1_STEPS: tuple[str, ...] = (
    "connect", "send_pos_on", "cycle_on", "trajectory", "cycle_off", "send_pos_off", "disconnect",
)
E4_STEPS: tuple[str, ...] = (
    "connect", "prog_idx", "send_pos_on", "cycle_on", "trajectory", "cycle_off", "send_pos_off",
    "result_wait", "vision_result", "disconnect",
)
STEPS = frozenset(S1_STEPS) | frozenset(E4_STEPS) | {"ping"}

perf = time.perf_counter


def parse_target(text: str, default_port: int = DEFAULT_PORT) -> tuple[str, int]:
    """``HOST:PORT``, ``[V6]:PORT`` or ``HOST`` → (host, port); ValueError if malformed."""
    target = Target.parse(text, default_port)
    return target.host, target.port


@dataclass(frozen=True)
class RobotFaults:
    """Deliberate deviations from a conforming robot (all off by default)."""

    #: B4: byte order of pose/tolerance/value block values ("little" breaks B4).
    float_byte_order: str | None = None
    #: B3: index of the first block (1 breaks B3 under the default profile).
    first_index: int | None = None
    #: B1/F5: announce this block length L in pose frames (the body stays 25 bytes).
    block_length: int | None = None
    #: T2: send poses in bursts of this many frames, every ``burst`` periods.
    burst: int = 1
    #: T2: the stream clock slows by this fraction per second (0.1: 10 % longer periods each second).
    drift: float = 0.0
    #: S1/S5: ``Send_Pos_Off`` stops the poses but leaves the stream connection open; it
    #: stays open ``stream_hold_s`` seconds after the command disconnect (or until the box closes it).
    leave_stream_open: bool = False
    stream_hold_s: float = 1.0
    #: R3: send every frame in pieces of this many bytes.
    segment_size: int | None = None
    #: Last word on every frame's bytes: ``hook(frame, data) -> data``.
    encode_hook: Callable[[Frame, bytes], bytes] | None = None

    def __post_init__(self) -> None:
        if self.float_byte_order not in (None, "big", "little"):
            raise ValueError("float_byte_order must be 'big', 'little' or None")
        if self.first_index is not None and not 0 <= self.first_index <= 255:
            raise ValueError("first_index must be 0..255")
        if self.block_length is not None and not 0 <= self.block_length <= 0xFFFF:
            raise ValueError("block_length must be 0..65535")
        if self.burst < 1:
            raise ValueError("burst must be at least 1")
        if self.segment_size is not None and self.segment_size < 1:
            raise ValueError("segment_size must be at least 1")
        if not 0 <= self.stream_hold_s <= 600:
            raise ValueError("stream_hold_s must be 0..600 seconds")


@dataclass
class TimelineEntry:
    """One line of the session's timeline: a request (with its answer) or a connection event."""

    t_ms: float  # since the session started
    conn: str  # "cmd", "stream" or "-"
    text: str
    answer: str | None = None
    latency_ms: float | None = None
    problem: str | None = None

    def format(self) -> str:
        line = f"{self.t_ms:9.1f} ms  {self.conn:<6}  {self.text}"
        if self.answer is not None:
            line += f"  <- {self.answer}"
        if self.latency_ms is not None:
            line += f"  ({self.latency_ms:.2f} ms)"
        if self.problem:
            line += f"  !! {self.problem}"
        return line


@dataclass
class RobotResult:
    """What a session did: verdict, timeline and figures."""

    exit_code: int = EXIT_OK
    reason: str = "clean session"
    steps: tuple[str, ...] = ()
    timeline: list[TimelineEntry] = field(default_factory=list)
    problems: list[tuple[int, str]] = field(default_factory=list)
    poses_sent: int = 0
    poses_answered: int = 0
    pose_latencies_ms: list[float] = field(default_factory=list)
    command_latencies_ms: dict[str, float] = field(default_factory=dict)
    send_intervals_ms: list[float] = field(default_factory=list)
    nominal_interval_ms: float = 20.0
    prog_idx_answer: int | None = None
    vision_result: int | None = None
    duration_ms: float = 0.0

    @property
    def ok(self) -> bool:
        return self.exit_code == EXIT_OK

    def latency(self, q: float) -> float:
        """The q-th percentile of the stream's answer latencies (ms); NaN without answers."""
        return percentile(self.pose_latencies_ms, q)

    @property
    def jitter_ms(self) -> tuple[float, float]:
        """Send-interval jitter: (mean absolute, max absolute) deviation from the nominal period."""
        dev = [abs(i - self.nominal_interval_ms) for i in self.send_intervals_ms]
        return (statistics.fmean(dev), max(dev)) if dev else (math.nan, math.nan)

    def format_timeline(self) -> str:
        return "\n".join(entry.format() for entry in sorted(self.timeline, key=lambda e: e.t_ms))

    def format_summary(self) -> str:
        lines = [
            f"poses sent {self.poses_sent}, answered {self.poses_answered}",
            f"pose answer latency ms: p50 {self.latency(50):.2f}  p99 {self.latency(99):.2f}  "
            f"max {self.latency(100):.2f}",
        ]
        mean, worst = self.jitter_ms
        lines.append(f"send-interval jitter ms (nominal {self.nominal_interval_ms:.2f}): mean {mean:.2f}  max {worst:.2f}")
        if self.command_latencies_ms:
            lines.append("command answers ms: " + "  ".join(f"{k} {v:.2f}" for k, v in self.command_latencies_ms.items()))
        if self.prog_idx_answer is not None:
            lines.append(f"ProgIdx answer: {self.prog_idx_answer}")
        if self.vision_result is not None:
            try:
                name = ResultCode(self.vision_result).name
            except ValueError:
                name = "unlisted"
            lines.append(f"vision result: {self.vision_result} ({name})")
        for code, reason in self.problems[1:]:
            lines.append(f"also: {reason} (exit {code})")
        verdict = "OK" if self.ok else "FAIL"
        lines.append(f"{verdict}: {self.reason} (exit {self.exit_code})")
        return "\n".join(lines)


class _Stop(Exception):
    """Ends the session with an exit code and a one-line reason."""

    def __init__(self, code: int, reason: str) -> None:
        super().__init__(reason)
        self.code = code
        self.reason = reason


class _Link(asyncio.BufferedProtocol):
    """One robot connection: bytes out, decoder events in with their arrival time."""

    def __init__(self, name: str, profile: Profile, on_event: Callable[[float, Frame | ProtocolError], None],
                 wake: Callable[[], None]) -> None:
        self.name = name
        self.decoder = StreamDecoder(profile, TransferType.BOX_TO_ROBOT)
        self.on_event = on_event
        self.wake = wake
        self.transport: asyncio.Transport | None = None
        self.buffer = memoryview(bytearray(1 << 16))
        self.eof = False
        self.lost = False
        self.closing = False

    def connection_made(self, transport: asyncio.BaseTransport) -> None:
        self.transport = transport  # type: ignore[assignment]

    def get_buffer(self, sizehint: int) -> memoryview:
        return self.buffer

    def buffer_updated(self, nbytes: int) -> None:
        now = perf()
        self.decoder.receive_data(self.buffer[:nbytes].tobytes())
        for event in self.decoder.events():
            self.on_event(now, event)
        self.wake()

    def eof_received(self) -> bool:
        self.eof = True
        self.wake()
        return False

    def connection_lost(self, exc: Exception | None) -> None:
        self.lost = True
        self.eof = True
        self.wake()

    def write(self, data: bytes, segment: int | None = None) -> None:
        transport = self.transport
        if transport is None or transport.is_closing():
            raise _Stop(EXIT_CONNECTION, f"the {self.name} connection is closed")
        if segment:
            for i in range(0, len(data), segment):
                transport.write(data[i : i + segment])
        else:
            transport.write(data)

    def close(self) -> None:
        self.closing = True
        if self.transport is not None and not self.transport.is_closing():
            self.transport.close()


class RobotSession:
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
        self.profile = profile
        self.duration = duration
        self.extension = extension
        self.program_index = program_index
        self.result_wait = result_wait
        self.trajectory = trajectory or PrimerTrajectory(duration=duration)
        self.faults = faults or RobotFaults()
        if steps is None:
            steps = E4_STEPS if extension else S1_STEPS
            if ping:
                steps = (steps[0], "ping", *steps[1:])
        unknown = [s for s in steps if s not in STEPS]
        if unknown:
            raise ValueError(f"unknown session steps: {', '.join(unknown)}; known: {', '.join(sorted(STEPS))}")
        self.steps = tuple(steps)
        self.stop_on_error = stop_on_error
        faults_ = self.faults
        encode_profile = profile
        if faults_.float_byte_order is not None:
            encode_profile = profile.replace(float_byte_order=faults_.float_byte_order)
        self._codec = codec_for(encode_profile)
        self._first_index = faults_.first_index if faults_.first_index is not None else profile.first_index
        self.time_out = profile.time_out_ms / 1000.0
        self.vision_time_out = profile.vision_time_out_ms / 1000.0
        self.period = 1.0 / profile.pose_rate_hz
        # state
        self.result = RobotResult(steps=self.steps, nominal_interval_ms=self.period * 1000.0)
        self._t0 = 0.0
        self._cmd: _Link | None = None
        self._stream: _Link | None = None
        self._cmd_events: deque[tuple[float, Frame | ProtocolError]] = deque()
        self._outstanding: deque[tuple[int, float, TimelineEntry]] = deque()
        self._wake = asyncio.Event()
        self._failure: _Stop | None = None
        self._sender: asyncio.Task[None] | None = None
        self._stop_poses = False
        self._cycle_start: float | None = None
        self._cycle_end: float | None = None
        self._last_send = 0.0

    # -- bookkeeping -----------------------------------------------------------------------------
    def _ms(self, t: float) -> float:
        return (t - self._t0) * 1000.0

    def _note(self, conn: str, text: str, t: float | None = None) -> TimelineEntry:
        entry = TimelineEntry(self._ms(perf() if t is None else t), conn, text)
        self.result.timeline.append(entry)
        return entry

    def _problem(self, code: int, reason: str, entry: TimelineEntry | None = None, fatal: bool = False) -> None:
        """Record a problem; stop the session unless it may go on (``stop_on_error=False``)."""
        if entry is not None:
            entry.problem = reason
        self.result.problems.append((code, reason))
        if fatal or self.stop_on_error or code in (EXIT_CONNECTION, EXIT_TIMEOUT):
            stop = _Stop(code, reason)
            if self._failure is None:
                self._failure = stop
            self._wake.set()
            raise stop

    def _signal(self) -> None:
        self._wake.set()

    async def _until(self, done: Callable[[], bool], timeout: float, on_timeout: Callable[[], None]) -> None:
        """Wait until ``done()``; a stream failure ends the wait; ``on_timeout()`` after ``timeout`` s."""
        deadline = perf() + timeout
        while True:
            if self._failure is not None:
                raise self._failure
            if done():
                return
            remaining = deadline - perf()
            if remaining <= 0:
                on_timeout()
                return
            self._wake.clear()
            with contextlib.suppress(asyncio.TimeoutError):
                await asyncio.wait_for(self._wake.wait(), remaining)

    async def _sleep(self, seconds: float) -> None:
        """Sleep, but end the session at once if the stream fails meanwhile."""
        await self._until(lambda: False, seconds, lambda: None)

    def _encode(self, frame: Frame) -> bytes:
        data = self._codec.encode(frame)
        faults = self.faults
        if faults.block_length is not None and frame.blocks:
            data = data[:8] + faults.block_length.to_bytes(2, self.profile.byte_order) + data[10:]  # type: ignore[arg-type]
        if faults.encode_hook is not None:
            data = faults.encode_hook(frame, data)
        return data

    # -- running ---------------------------------------------------------------------------------
    async def run(self) -> RobotResult:
        """Play the session; never raises for anything the box or the network does."""
        self._t0 = perf()
        result = self.result
        try:
            for step in self.steps:
                await getattr(self, "_step_" + step)()
                if self._failure is not None:
                    raise self._failure
        except _Stop as stop:
            result.exit_code, result.reason = stop.code, stop.reason
        except OSError as exc:  # anything the socket layer throws at us
            result.exit_code, result.reason = EXIT_CONNECTION, f"network error: {exc}"
        finally:
            await self._teardown()
            result.duration_ms = self._ms(perf())
        if result.exit_code == EXIT_OK and result.problems:
            result.exit_code, result.reason = result.problems[0]
        return result

    async def _teardown(self) -> None:
        self._stop_poses = True
        if self._sender is not None and not self._sender.done():
            self._sender.cancel()
            with contextlib.suppress(asyncio.CancelledError, _Stop, Exception):
                await self._sender
        links = (self._cmd, self._stream)
        if self.faults.leave_stream_open and self._stream is not None:
            # the leaked stream: the command connection closes first, the stream after the hold
            if self._cmd is not None and not self._cmd.lost:
                self._cmd.close()
            deadline = perf() + self.faults.stream_hold_s
            while not self._stream.lost and perf() < deadline:
                await asyncio.sleep(0.01)
            links = (self._cmd, self._stream)
        for link in links:
            if link is not None and not link.lost:
                link.close()
        for link in (self._cmd, self._stream):
            if link is not None and not link.lost:
                deadline = perf() + 1.0
                while not link.lost and perf() < deadline:
                    await asyncio.sleep(0.005)

    async def _connect(self, name: str, address: tuple[str, int], on_event: Callable[..., None]) -> _Link:
        loop = asyncio.get_running_loop()
        host, port = address
        link = _Link(name, self.profile, on_event, self._signal)
        where = f"{host}:{port}" if ":" not in host else f"[{host}]:{port}"
        t = perf()
        try:
            await asyncio.wait_for(loop.create_connection(lambda: link, host, port), self.time_out)
        except asyncio.TimeoutError:
            self._problem(EXIT_TIMEOUT, f"connecting the {name} connection to {where} timed out after "
                          f"time_out {self.profile.time_out_ms} ms (T1)", fatal=True)
        except ConnectionRefusedError:
            self._problem(EXIT_CONNECTION, f"connection refused by {where} ({name} connection)", fatal=True)
        except OSError as exc:
            self._problem(EXIT_CONNECTION, f"cannot connect the {name} connection to {where}: {exc.strerror or exc}",
                          fatal=True)
        self._note(name, f"connected to {where}", t)
        return link

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
        entry = self._note("cmd", "-> " + _summary(frame), t_sent)
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
            self._problem(EXIT_MISBEHAVED, f"malformed answer to {action.name}: {event}", entry)
            return None, entry
        entry.answer = _summary(event)
        if event.action is not action:
            self._problem(EXIT_MISBEHAVED, f"{action.name} answered with action {event.action.name} "
                          "(A2: an answer echoes its request's action)", entry)
            return None, entry
        return event, entry

    def _expect_ok(self, answer_frame: Frame | None, entry: TimelineEntry, clause: str) -> None:
        if answer_frame is not None and answer_frame.error_code != ErrorCode.OK:
            action = answer_frame.action.name
            self._problem(EXIT_MISBEHAVED, f"{action} answered 0x{answer_frame.error_code:04X} where 0000 expected "
                          f"({clause})", entry)

    # -- steps -----------------------------------------------------------------------------------------
    async def _step_connect(self) -> None:
        self._cmd = await self._connect("cmd", self.target, self._on_cmd_event)

    async def _step_ping(self) -> None:
        frame, entry = await self._command(Action.NONE)
        self._expect_ok(frame, entry, "A4")

    async def _step_prog_idx(self) -> None:
        blocks = value_blocks([self.program_index], self._first_index)
        frame, entry = await self._command(Action.PROG_IDX, blocks)
        if frame is None:
            return
        value = frame.blocks[0].value if frame.blocks and isinstance(frame.blocks[0], ValueBlock) else None
        self.result.prog_idx_answer = value
        if value == self.program_index and value != ResultCode.CONFLICT:
            if frame.error_code != ErrorCode.OK:
                entry.problem = f"error field 0x{frame.error_code:04X} ignored (E2: it stays 0000)"
            return
        if value == ResultCode.CONFLICT:
            self._problem(EXIT_NOT_READY, f"box not ready for program {self.program_index} (ProgIdx answered 409, E2)",
                          entry, fatal=True)
        self._problem(EXIT_MISBEHAVED, f"ProgIdx {self.program_index} answered with value {value}, expected "
                      f"{self.program_index} or 409 (E2)", entry)

    async def _step_send_pos_on(self) -> None:
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

    async def _step_cycle_on(self) -> None:
        frame, entry = await self._command(Action.CYCLE_ON)
        if frame is not None and frame.error_code == ErrorCode.NOT_READY:
            self._problem(EXIT_NOT_READY, "box not ready (CycleOn answered 0001, S2: the cycle is inconclusive)",
                          entry, fatal=True)
        self._expect_ok(frame, entry, "S1")
        self._cycle_start = perf()

    async def _step_trajectory(self) -> None:
        if self._cycle_start is None:
            self._cycle_start = perf()
        self._note("-", f"primer trajectory, {self.duration:g} s")
        await self._sleep(self.duration)

    async def _step_cycle_off(self) -> None:
        frame, entry = await self._command(Action.CYCLE_OFF)
        self._cycle_end = perf()
        self._expect_ok(frame, entry, "S1")

    async def _step_send_pos_off(self) -> None:
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

    async def _step_result_wait(self) -> None:
        await self._sleep(self.result_wait)

    async def _step_vision_result(self) -> None:
        frame, entry = await self._command(Action.VISION_RESULT, timeout=self.vision_time_out,
                                           bound="vision_time_out")
        if frame is None:
            return
        value = frame.blocks[0].value if frame.blocks and isinstance(frame.blocks[0], ValueBlock) else None
        self.result.vision_result = value
        if value in (ResultCode.EMPTY, ResultCode.NO_ANSWER):
            self._problem(EXIT_MISBEHAVED, f"result request answered ResultCode {value}, which only the robot "
                          "writes (E3)", entry)
        elif value not in SENDABLE_RESULTS:
            entry.problem = f"unlisted ResultCode {value} (E3: informational)"
        elif frame.error_code != ErrorCode.OK:
            entry.problem = f"error field 0x{frame.error_code:04X} ignored (E2/E3: it stays 0000)"

    async def _step_disconnect(self) -> None:
        link = self._cmd
        if link is not None:
            if self._cmd_events:
                _, extra = self._cmd_events.popleft()
                what = extra.describe() if isinstance(extra, Frame) else str(extra)
                self._problem(EXIT_MISBEHAVED, f"unsolicited frame on the command connection: {what} (A1)")
            link.close()
            self._note("cmd", "disconnected")

    def _check_failure(self) -> None:
        if self._failure is not None:
            raise self._failure

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
                    entry = TimelineEntry(self._ms(now), "stream", f"-> POSE #{seq} {_pose_text(frame)}")
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
        except _Stop as stop:  # recorded by _problem, or a write to a closed stream
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
                self._problem(EXIT_MISBEHAVED, f"malformed answer to pose #{seq}: {event}", entry)
                return
            entry.answer = _summary(event)
            self.result.poses_answered += 1
            self.result.pose_latencies_ms.append(latency)
            if event.action is not Action.POSE:
                self._problem(EXIT_MISBEHAVED, f"pose #{seq} answered with action {event.action.name} (A2)", entry)
            elif event.error_code != ErrorCode.OK:
                self._problem(EXIT_MISBEHAVED, f"pose #{seq} answered 0x{event.error_code:04X} where 0000 expected "
                              "(S3)", entry)
        except _Stop:
            pass  # recorded in self._failure; the main flow ends the session


def _summary(frame: Frame) -> str:
    text = f"{frame.action.name}"
    if frame.blocks and isinstance(frame.blocks[0], ValueBlock):
        text += " value=" + ",".join(str(b.value) for b in frame.blocks)  # type: ignore[union-attr]
    if frame.transfer_type == TransferType.BOX_TO_ROBOT or frame.error_code:
        text += f" {frame.error_code:04X}"
    return text


def _pose_text(frame: Frame) -> str:
    pose = frame.blocks[0].pose  # type: ignore[union-attr]
    return "(" + ", ".join(f"{v:.1f}" for v in pose[:3]) + " | " + ", ".join(f"{v:.1f}" for v in pose[3:]) + ")"


def run_robot(session: RobotSession, loop: str = "asyncio") -> RobotResult:
    """Run a session to completion from synchronous code."""
    from .loop import run_loop

    return run_loop(session.run(), loop)  # type: ignore[no-any-return]


__all__ = [
    "E4_STEPS", "EXIT_CONNECTION", "EXIT_MISBEHAVED", "EXIT_NOT_READY", "EXIT_OK", "EXIT_TIMEOUT", "RobotFaults",
    "RobotResult", "RobotSession", "S1_STEPS", "STEPS", "TimelineEntry", "parse_target", "run_robot",
]

"""What every step of a robot session shares, over asyncio: :class:`Link` (one TCP connection,
decoder events in with their arrival time), :class:`Stop` (ends the session with an exit code
and a one-line reason) and :class:`SessionIO`, the base of :class:`~.robot.RobotSession`:
the timeline and its problems, waits that end at once when the stream fails, connecting,
encoding with the robot's faults, and the teardown.
"""

from __future__ import annotations

import asyncio
import contextlib
import time
from collections.abc import Callable
from typing import cast

from ...harness.target import Target
from ...protocol import Frame, Profile, ProtocolError, StreamDecoder, TransferType, codec_for
from ...protocol.constants import HEADER_FIELDS
from .robot_result import EXIT_CONNECTION, EXIT_OK, EXIT_TIMEOUT, RobotResult, TimelineEntry
from .robot_steps import Judgement, RobotFaults

perf = time.perf_counter


class Stop(Exception):
    """Ends the session with an exit code and a one-line reason."""

    def __init__(self, code: int, reason: str) -> None:
        super().__init__(reason)
        self.code = code
        self.reason = reason


class Link(asyncio.BufferedProtocol):
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
        self.transport = cast(asyncio.Transport, transport)  # a stream connection's transport

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
            raise Stop(EXIT_CONNECTION, f"the {self.name} connection is closed")
        if segment:
            for i in range(0, len(data), segment):
                transport.write(data[i : i + segment])
        else:
            transport.write(data)

    def close(self) -> None:
        self.closing = True
        if self.transport is not None and not self.transport.is_closing():
            self.transport.close()


class SessionIO:
    """The connections, the clock and the record of a session (:class:`~.robot.RobotSession` plays the steps)."""

    def __init__(self, profile: Profile, faults: RobotFaults, steps: tuple[str, ...], stop_on_error: bool) -> None:
        self.profile = profile
        self.faults = faults
        self.steps = steps
        self.stop_on_error = stop_on_error
        encode_profile = profile
        if faults.float_byte_order is not None:
            encode_profile = profile.replace(float_byte_order=faults.float_byte_order)
        self._codec = codec_for(encode_profile)
        self._first_index = faults.first_index if faults.first_index is not None else profile.first_index
        self.time_out = profile.time_out_s
        self.vision_time_out = profile.vision_time_out_s
        self.period = 1.0 / profile.pose_rate_hz
        # state
        self.result = RobotResult(steps=self.steps, nominal_interval_ms=self.period * 1000.0)
        self._t0 = 0.0
        self._cmd: Link | None = None
        self._stream: Link | None = None
        self._wake = asyncio.Event()
        self._failure: Stop | None = None
        self._sender: asyncio.Task[None] | None = None
        self._stop_poses = False

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
            stop = Stop(code, reason)
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
            at, width = HEADER_FIELDS["block_length"]  # B1/F5: announce the wrong L, keep the body
            data = data[:at] + self._codec.pack_u16(faults.block_length) + data[at + width:]
        if faults.encode_hook is not None:
            data = faults.encode_hook(frame, data)
        return data

    def _judge(self, judgement: Judgement, entry: TimelineEntry) -> None:
        """A step's judgement of an answer: a problem, an informational note, or nothing."""
        if judgement.code != EXIT_OK:
            self._problem(judgement.code, judgement.reason, entry, fatal=judgement.fatal)
        elif judgement.reason:
            entry.problem = judgement.reason

    def _check_failure(self) -> None:
        if self._failure is not None:
            raise self._failure

    # -- connecting and closing ---------------------------------------------------------------------------
    async def _connect(self, name: str, address: tuple[str, int], on_event: Callable[..., None]) -> Link:
        loop = asyncio.get_running_loop()
        host, port = address
        link = Link(name, self.profile, on_event, self._signal)
        where = str(Target(host, port))  # [v6]:port
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

    async def _teardown(self) -> None:
        self._stop_poses = True
        if self._sender is not None and not self._sender.done():
            self._sender.cancel()
            with contextlib.suppress(asyncio.CancelledError, Stop, Exception):
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


__all__ = ["Link", "SessionIO", "Stop"]

"""The line as the robot sees it: every byte the monitor forwards becomes a packet.

The monitor holds two sockets per robot connection (robot ↔ monitor, monitor ↔ box).
What it records is one TCP connection from the robot's address and port to the box's:
the bytes the robot sent and the bytes the robot received (after any injected fault),
as packets with real time stamps (:mod:`conformance.evidence.packet_builder` draws them: a
handshake, data segments, FIN or RST). Each packet gets the next frame number, goes into
the pcapng ring and into the judging engine (:class:`~conformance.analyze.engine.Feed`,
the one ``analyze`` runs), so ``analyze`` on the ring's file finds what the monitor found.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass

from ..analyze.engine import Feed
from ..evidence import packet_builder as pk
from ..evidence.pcapng import LINKTYPE_ETHERNET
from ..harness.transcript import ConnectionInfo, Endpoint
from .ring import Ring

__all__ = ["Line", "Wire"]

_ACK, _PSH = 0x10, 0x08


@dataclass
class Line:
    """One recorded robot connection (TCP) or robot address (UDP)."""

    number: int
    flow: pk.Flow
    robot: str
    box: str
    transport: str = "tcp"

    @property
    def label(self) -> str:
        return f"{self.robot} → {self.box}"


class Wire:
    """Frame numbers, the ring and the engine, fed in one order."""

    def __init__(self, feed: Feed, ring: Ring | None, run_id: str,
                 clock: Callable[[], float] = time.time) -> None:
        self.feed = feed
        self.ring = ring
        self.run_id = run_id
        self.clock = clock
        self.frames = 0
        self.lines = 0
        self.bytes = {"robot": 0, "box": 0}
        self.last_t = clock()  # the time stamp of the latest packet
        #: packets the engine failed on (the suite's own fault: forwarding goes on), and the first failure
        self.judge_errors = 0
        self.judge_error: str | None = None

    def line(self, robot: tuple[str, int], box: tuple[str, int], transport: str = "tcp") -> Line:
        self.lines += 1
        info = ConnectionInfo(self.lines, transport, Endpoint(robot[0], robot[1]), Endpoint(box[0], box[1]))
        flow = pk.new_flow(info, self.run_id)
        return Line(self.lines, flow, str(info.local), str(info.remote), transport)

    # -- packets -------------------------------------------------------------------------------
    def _emit(self, frames: list[bytes], comments: list[str] | None = None) -> int:
        """Number, write and judge ``frames``; ``comments`` go on the first. Its frame number."""
        first = self.frames + 1
        # the engine gets the time stamp the pcapng keeps (microseconds), so analyze on it computes the same
        t = self.last_t = round(self.clock() * 1_000_000) / 1_000_000
        ring, feed = self.ring, self.feed
        for frame in frames:
            self.frames += 1
            if ring is not None:
                ring.write(frame, t, self.frames, comments if self.frames == first else None)
            try:
                feed.packet(LINKTYPE_ETHERNET, frame, self.frames, t)
            except Exception as exc:  # noqa: BLE001 - the line goes on; the suite's own fault is reported
                self.judge_errors += 1
                if self.judge_error is None:
                    self.judge_error = f"frame {self.frames}: {type(exc).__name__}: {exc}"
        return first

    def opened(self, line: Line) -> int:
        return self._emit(pk.handshake(line.flow, passive=False))

    def data(self, line: Line, from_robot: bool, payload: bytes, comments: list[str] | None = None) -> int:
        """Bytes one side sent (``from_robot``) or the robot received; frame number of the first segment."""
        self.bytes["robot" if from_robot else "box"] += len(payload)
        flow = line.flow
        if line.transport == "udp":
            return self._emit([pk.udp(flow, from_robot, payload)], comments)
        frames = []
        for start in range(0, len(payload), pk.MAX_SEGMENT):
            chunk = payload[start : start + pk.MAX_SEGMENT]
            frames.append(pk.tcp(flow, from_robot, _ACK | _PSH, payload=chunk))
            flow.seq[from_robot] = (flow.seq[from_robot] + len(chunk)) & 0xFFFFFFFF
        return self._emit(frames, comments)

    def marker(self, line: Line, from_robot: bool, comment: str) -> int:
        """A pure ACK carrying ``comment`` (an injected fault that leaves no bytes on the robot's line)."""
        return self._emit([pk.tcp(line.flow, from_robot, _ACK)], [comment])

    def closed(self, line: Line, from_robot: bool, reset: bool = False, comment: str = "") -> int | None:
        """One side's FIN (or RST); nothing after a reset or a second FIN from that side."""
        flow = line.flow
        if flow.reset or flow.fin[from_robot] or line.transport == "udp":
            return None
        frames = [pk.rst(flow, from_robot)] if reset else pk.fin(flow, from_robot)
        return self._emit(frames, [comment] if comment else None)

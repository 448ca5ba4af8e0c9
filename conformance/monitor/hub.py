"""The monitor's state: the wire, the engine, the ring, the faults and what the robot did after them.

:class:`Hub` is what the proxies (:mod:`.proxy`, :mod:`.udp_proxy`) tell about each connection:
it opened, one side sent bytes, one side closed, the box could not be reached, a fault
was injected. It keeps the counts the live view shows. Nothing here does I/O but the
ring's writes.
"""

from __future__ import annotations

import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..analyze.analysis_context import AnalyzeConfig, Context
from ..analyze.engine import Feed
from ..analyze.findings import Observation
from .alarms import Alarms
from .faults import Fault, FaultPlan
from .line_recording import Line, Wire
from .live_findings import Cause, LiveFindings
from .reactions import Injection, Reactions
from .ring import Ring
from .split import Splitter
from .tally import Buckets, ObservedSeries, Tally

__all__ = ["Conn", "Hub", "MonitorSettings"]

EVENTS_KEPT = 200
OUTSTANDING = 4096  # request frames remembered per connection and action


@dataclass
class MonitorSettings:
    listen: tuple[str, int]
    upstream: tuple[str, int]
    config: AnalyzeConfig
    pcap_dir: Path | None
    ring_files: int = 10
    ring_mb: float = 100.0
    faults: list[str] = field(default_factory=list)
    seed: int = 0
    udp: bool = False
    connect_timeout_s: float = 5.0
    metrics: tuple[str, int] | None = None  # --metrics HOST:PORT (the address got, once listening)
    http: tuple[str, int] | None = None  # --http HOST:PORT
    #: the package's run ID, device under test and tester (Acceptance.to_dict()), for the reports
    acceptance: dict[str, Any] | None = None


@dataclass
class Conn:
    """One robot connection through the monitor."""

    line: Line
    robot_host: str
    opened: float
    requests: Splitter | None = None  # the robot's requests, when faults are on (for the reaction log)
    closed: bool = False
    #: per action, the frame numbers of the requests not answered yet (faults on; bounded)
    outstanding: dict[int, deque[int]] = field(default_factory=dict)
    judge: Any = None  # the engine's judge of this connection (its counts, for the live view)


def judge_counts(j: Any) -> tuple[int, int, int]:
    """(requests, answers, poses) the engine's judge of one connection has seen."""
    if j is None:
        return (0, 0, 0)
    return (sum(j.robot_counts.values()) + j.poses + j.robot_errors,
            sum(j.box_counts.values()) + j.box_poses + j.box_errors, j.poses)


class Hub:
    def __init__(self, settings: MonitorSettings, on_finding: Callable[[str, str, Observation, Cause], None] | None = None,
                 clock: Callable[[], float] = time.time) -> None:
        self.settings = settings
        self.clock = clock
        self.started = clock()
        profile = settings.config.profile
        self.alarms = Alarms(profile.time_out_ms, profile.vision_time_out_ms, profile.pose_rate_hz,
                             settings.config.rate_tolerance)
        self.on_finding = on_finding
        self.findings = LiveFindings(self._finding, clock)
        self.feed = Feed(settings.config, settings.pcap_dir, self.findings)
        # latency histograms for the metrics: the engine's command series feeds one, each pose answer the other
        self.command_latency, self.pose_latency = Buckets(), Buckets()
        self.feed.ctx.latency = ObservedSeries(self.command_latency)
        self.feed.ctx.observe_pose = self.pose_latency.observe  # type: ignore[attr-defined]
        self.tally = Tally()  # the counts of the connections gone
        self.ring = (Ring(settings.pcap_dir, settings.ring_files, settings.ring_mb)
                     if settings.pcap_dir is not None else None)
        self.wire = Wire(self.feed, self.ring, f"monitor-{int(self.started)}", clock)
        self.faults = FaultPlan(settings.faults, settings.seed)
        self.reactions = Reactions(settings.config.profile)
        self.open: dict[int, Conn] = {}
        self.connections = 0
        self.upstream_failures = 0
        self.events: deque[str] = deque(maxlen=EVENTS_KEPT)  # the monitor's own events (upstream failures ...)
        self.big_endian = settings.config.profile.byte_order == "big"
        self.counted = [0, 0, 0]  # requests, answers, poses of the connections that are gone

    @property
    def ctx(self) -> Context:
        return self.feed.ctx

    def _finding(self, clause: str, side: str, finding: Observation, cause: Cause) -> None:
        self.alarms.finding(clause, side, finding.text, finding.frames, self.clock())
        if self.on_finding is not None:
            self.on_finding(clause, side, finding, cause)

    def tick(self) -> None:
        """About twice a second: raise and clear the live alarms."""
        self.alarms.check([(n, c.judge, not c.closed) for n, c in self.open.items()], self.clock(),
                          self.findings.faulted)

    def totals(self) -> Tally:
        """The counts of every connection so far (those gone and those open)."""
        return self.tally.with_open(c.judge for c in self.open.values() if c.judge is not None)

    def elapsed(self) -> float:
        return self.clock() - self.started

    def note(self, text: str) -> None:
        self.events.append(f"{time.strftime('%H:%M:%S')} {text}")

    # -- connections ------------------------------------------------------------------------------
    def opened(self, robot: tuple[str, int], box: tuple[str, int], transport: str = "tcp") -> Conn:
        line = self.wire.line(robot, box, transport)
        conn = Conn(line, robot[0], self.clock(), Splitter(self.big_endian) if self.faults else None)
        self.connections += 1
        self.open[line.number] = conn
        if transport == "tcp":
            self.wire.opened(line)
            followed = self.feed.conversations.open.get(line.number)  # the engine numbers connections as we do
            conn.judge = followed.judge if followed is not None else None
        if self.faults:
            self.reactions.connected(robot[0], conn.opened)
        return conn

    def upstream_failed(self, conn: Conn, why: str) -> None:
        """The box could not be reached for this robot connection: the robot's side is reset."""
        self.upstream_failures += 1
        text = f"connection {conn.line.number} from {conn.line.robot}: the box {conn.line.box} {why}; the robot's " \
               "connection was reset"
        self.note(text)
        self.alarms.refused(conn.line.number, text, self.clock())
        self.closed(conn, from_robot=False, reset=True, comment=f"monitor: {text}")

    def upstream_ok(self, conn: Conn) -> None:
        """The box accepted the connection made for this robot connection."""
        self.alarms.accepted(conn.line.number, self.clock())

    def data(self, conn: Conn, from_robot: bool, payload: bytes, comments: list[str] | None = None) -> int:
        frame = self.wire.data(conn.line, from_robot, payload, comments)
        if from_robot and conn.requests is not None:
            t = self.clock()
            for _piece, action in conn.requests.feed(payload):
                if action is not None:
                    self.reactions.request(conn.line.number, action, t)
                    waiting = conn.outstanding.get(action)
                    if waiting is None:
                        waiting = conn.outstanding[action] = deque(maxlen=OUTSTANDING)
                    waiting.append(frame)
        return frame

    def answered(self, conn: Conn, action: int) -> int | None:
        """The box answers ``action``: the frame of the request it answers (the oldest waiting), if known."""
        waiting = conn.outstanding.get(action)
        return waiting.popleft() if waiting else None

    def closed(self, conn: Conn, from_robot: bool, reset: bool = False, comment: str = "") -> None:
        if self.wire.closed(conn.line, from_robot, reset, comment) is not None and from_robot and self.faults:
            self.reactions.closed(conn.line.number, reset, self.clock())

    def gone(self, conn: Conn) -> None:
        """Both sockets of the connection are closed."""
        conn.closed = True
        if self.open.pop(conn.line.number, None) is not None:
            self.counted = [a + b for a, b in zip(self.counted, judge_counts(conn.judge))]
            self.tally.add(conn.judge)

    def counts(self) -> tuple[int, int, int]:
        """(requests, answers, poses) over every TCP connection so far."""
        totals = list(self.counted)
        for conn in self.open.values():
            totals = [a + b for a, b in zip(totals, judge_counts(conn.judge))]
        return totals[0], totals[1], totals[2]

    # -- faults -------------------------------------------------------------------------------------
    def pick(self, action: int) -> Fault | None:
        return self.faults.pick(action, self.elapsed()) if self.faults else None

    def injected(self, conn: Conn, fault: Fault, action: int, what: str, request: int | None = None) -> Injection:
        """Call just before writing what carries the fault (the next frame); the box's findings on the
        connection from that frame on, or from the ``request`` it answers, are the fault's."""
        frame = self.wire.frames + 1
        self.note(f"connection {conn.line.number}: injected {fault.spec}: {what}")
        inj = self.reactions.injected(fault.spec, fault.kind, fault.clause, conn.line.number, conn.robot_host,
                                      action, self.clock(), frame, what)
        self.findings.fault_on(conn.line.number, min(frame, request or frame), inj.id, frame)
        return inj

    def comment(self, fault: Fault, what: str) -> str:
        return f"isight-conformance monitor: INJECTED FAULT ({fault.spec}): {what}; not the box's doing"

    # -- the end ------------------------------------------------------------------------------------
    def finish(self) -> None:
        """The monitor stops: each connection still open gets an empty ACK saying so (the capture's end
        is then the moment the monitor stopped, for ``analyze`` as for the engine here), then the engine
        judges what is left as open at the end."""
        for conn in list(self.open.values()):
            if conn.line.transport == "tcp" and not conn.line.flow.reset:
                self.wire.marker(conn.line, False, "isight-conformance monitor: stopped while the connection was "
                                 "open")
        self.feed.finish(self.wire.last_t, self.wire.frames)
        if self.ring is not None:
            self.ring.close()

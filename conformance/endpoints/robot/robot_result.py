"""What a robot session did: its exit code and one-line reason, its timeline and its figures.

Plain data (no sockets or clocks): the driver (:mod:`.robot`) fills a :class:`RobotResult`
as the session goes; the ``robot`` command prints it.
"""

from __future__ import annotations

import math
import statistics
from dataclasses import dataclass, field

from ...model.exit_codes import EXIT_CONNECTION, EXIT_MISBEHAVED, EXIT_NOT_READY, EXIT_OK, EXIT_TIMEOUT
from ...model.percentiles import percentile
from ...protocol import Frame, ResultCode, TransferType
from ...protocol.frames import PoseBlock, ValueBlock


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


def frame_text(frame: Frame) -> str:
    """A frame in a timeline line: its action, value blocks and (in answers) error code."""
    text = f"{frame.action.name}"
    values = [str(b.value) for b in frame.blocks if isinstance(b, ValueBlock)]
    if values:
        text += " value=" + ",".join(values)
    if frame.transfer_type == TransferType.BOX_TO_ROBOT or frame.error_code:
        text += f" {frame.error_code:04X}"
    return text


def pose_text(frame: Frame) -> str:
    """A pose frame's pose in a timeline line: ``(x, y, z | w, p, r)``."""
    block = frame.blocks[0]
    assert isinstance(block, PoseBlock), frame
    pose = block.pose
    return "(" + ", ".join(f"{v:.1f}" for v in pose[:3]) + " | " + ", ".join(f"{v:.1f}" for v in pose[3:]) + ")"


__all__ = [
    "EXIT_CONNECTION", "EXIT_MISBEHAVED", "EXIT_NOT_READY", "EXIT_OK", "EXIT_TIMEOUT", "RobotResult", "TimelineEntry",
    "frame_text", "pose_text",
]

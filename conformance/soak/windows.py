"""What the soak measures, window by window, without keeping any per-frame history.

A :class:`SessionOutcome` is one robot session boiled down (its latencies go straight into
sketches and are dropped). A :class:`Window` accumulates outcomes, events and a resource
sample for one window of time (default a minute) and closes into a :class:`WindowRow`, a
dozen numbers, which is all the soak keeps: 480 of them for eight hours.
"""

from __future__ import annotations

import math
from collections import Counter
from dataclasses import dataclass, field
from typing import Any

from .sketch import LatencySketch

#: failure kinds of a session (what ended it), and the clause each one breaks
FAILURE_CLAUSE: dict[str, str] = {
    "connect": "S5",  # the box refused or did not accept a connection in time
    "closed": "R5",  # the box closed a live connection (dropped a robot it was serving)
    "timeout": "T1",  # an answer did not come within time_out
    "command-starved": "S4",  # a command went unanswered while the stream was being served
    "misbehaved": "S1",  # a wrong answer (action, code, malformed)
    "after-vanish": "R5",  # the rebooted robot, from a new port, was not served
}
#: how many example reasons a window keeps per failure kind
REASONS_KEPT = 2


@dataclass
class SessionOutcome:
    """One session of one robot, as the windows count it."""

    robot: int
    ok: bool
    #: "" when ok; else a key of FAILURE_CLAUSE, or "not-ready" (S2: inconclusive, not a failure)
    failure: str = ""
    reason: str = ""
    #: the planted event this session carried ("vanish", "reset", "stall", "burst") or ""
    event: str = ""
    #: the session came right after its robot vanished or was reset (it must be served)
    after_event: str = ""
    poses_sent: int = 0
    poses_answered: int = 0
    pose_latencies_ms: list[float] = field(default_factory=list)
    command_latencies_ms: list[float] = field(default_factory=list)
    connect_ms: list[float] = field(default_factory=list)
    #: answers later than time_out (they came, too late: T1)
    late: int = 0
    #: ProgIdx was answered 409, not ready (E2): the session was inconclusive
    prog_idx_conflict: bool = False


def _summary(sketch: LatencySketch) -> dict[str, float | int | None]:
    def r(value: float) -> float | None:
        return None if math.isnan(value) or math.isinf(value) else round(value, 4)

    return {"n": sketch.count, "p50": r(sketch.quantile(50)), "p99": r(sketch.quantile(99)), "max": r(sketch.quantile(100))}


@dataclass
class WindowRow:
    """A closed window: the figures every plot, trend and checkpoint reads."""

    index: int
    start_s: float
    end_s: float
    sessions_ok: int
    sessions_failed: int
    sessions_not_ready: int
    sessions_cut: int  # ended on purpose by a planted event (vanish, reset)
    sessions_total: int  # sessions judged since the soak began, at the window's end
    latency: dict[str, float | int | None]
    command: dict[str, float | int | None]
    connect: dict[str, float | int | None]
    answers_missing: int
    answers_late: int
    events: dict[str, int]
    failures: dict[str, int]
    reasons: dict[str, list[str]]
    resources: dict[str, float | None] = field(default_factory=dict)
    tester_stall_ms: float = 0.0

    def to_dict(self) -> dict[str, Any]:
        return dict(self.__dict__)

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> WindowRow:
        known = {k: data[k] for k in cls.__dataclass_fields__ if k in data}
        return cls(**known)

    @property
    def has_finding(self) -> bool:
        return bool(self.sessions_failed or self.answers_missing or self.answers_late)


class Window:
    """The open window: outcomes and events in, a :class:`WindowRow` out."""

    def __init__(self, index: int, start_s: float, time_out_ms: float) -> None:
        self.index = index
        self.start_s = start_s
        self.time_out_ms = time_out_ms
        self.latency = LatencySketch()
        self.command = LatencySketch()
        self.connect = LatencySketch()
        self.ok = self.failed = self.not_ready = self.cut = 0
        self.missing = self.late = 0
        self.events: Counter[str] = Counter()
        self.failures: Counter[str] = Counter()
        self.reasons: dict[str, list[str]] = {}

    def add(self, outcome: SessionOutcome) -> None:
        for value in outcome.pose_latencies_ms:
            self.latency.add(value)
        for value in outcome.command_latencies_ms:
            self.command.add(value)
        for value in outcome.connect_ms:
            self.connect.add(value)
        self.late += outcome.late
        if outcome.event in ("vanish", "reset"):
            self.cut += 1  # its unanswered poses were abandoned on purpose
            return
        if outcome.failure == "not-ready":
            self.not_ready += 1  # ended by the box's "not ready" (S2/E2): its poses in flight were dropped
            return
        self.missing += max(0, outcome.poses_sent - outcome.poses_answered)
        if outcome.ok:
            self.ok += 1
        else:
            self.failed += 1
            self.failures[outcome.failure] += 1
            kept = self.reasons.setdefault(outcome.failure, [])
            if len(kept) < REASONS_KEPT and outcome.reason not in kept:
                kept.append(outcome.reason)

    def note_event(self, kind: str, count: int = 1) -> None:
        self.events[kind] += count

    def close(self, end_s: float, sessions_before: int, resources: dict[str, float | None],
              tester_stall_ms: float) -> WindowRow:
        judged = self.ok + self.failed
        return WindowRow(
            self.index, round(self.start_s, 3), round(end_s, 3), self.ok, self.failed, self.not_ready, self.cut,
            sessions_before + judged, _summary(self.latency), _summary(self.command), _summary(self.connect),
            self.missing, self.late, dict(self.events), dict(self.failures), dict(self.reasons), resources,
            round(tester_stall_ms, 2),
        )


__all__ = ["FAILURE_CLAUSE", "SessionOutcome", "Window", "WindowRow"]

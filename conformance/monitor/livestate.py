"""What the live page shows, as one JSON document made every tick (sans-I/O but the clock).

:class:`Board` keeps what a single look at the hub cannot give: the pose rate since the
last tick and a short history of the latencies for the plot (:data:`HISTORY` ticks). Its
:meth:`Board.snapshot` is the page's state: the connections open (at most
:data:`SHOWN_CONNECTIONS`), sessions, frames and rates, the latencies, the alarms, the
root causes of the findings, and links to the ring's pcapng files and the reports.
"""

from __future__ import annotations

import math
import time
from collections import deque
from typing import Any

from ..model.percentiles import percentile
from .hub import Hub, judge_counts

__all__ = ["HISTORY", "REPORTS", "Board"]

HISTORY = 240  # ticks of latency history (two minutes at two ticks a second)
SHOWN_CONNECTIONS = 50
SHOWN_CAUSES = 30
SHOWN_ALARMS = 50
#: the report files the page links to (written at checkpoints and on stop)
REPORTS = ("report.html", "summary.json", "monitor.json", "junit.xml")


def _num(v: float) -> float | None:
    return None if math.isnan(v) else round(v, 3)


def _role(judge: Any) -> str:
    if judge is None or not (judge.robot_counts or judge.poses):
        return "unknown"
    return "command" if judge.robot_counts else "stream"


class Board:
    def __init__(self, hub: Hub, clock: Any = time.monotonic) -> None:
        self.hub = hub
        self.clock = clock
        self.history: deque[tuple[float, float | None, float | None, float | None]] = deque(maxlen=HISTORY)
        self.last = (clock(), 0, 0)  # (t, poses, frames)
        self.pose_rate = 0.0
        self.frame_rate = 0.0
        self.version = 0

    def tick(self) -> None:
        """Rates since the last tick and one point of latency history."""
        hub = self.hub
        requests, answers, poses = hub.counts()
        t = self.clock()
        t0, p0, f0 = self.last
        if t - t0 >= 0.2:
            self.pose_rate = (poses - p0) / (t - t0)
            self.frame_rate = (requests + answers - f0) / (t - t0)
            self.last = (t, poses, requests + answers)
        recent = self._recent_poses()
        lat = hub.ctx.latency
        self.history.append((round(hub.elapsed(), 2), _num(percentile(recent, 50)) if recent else None,
                             _num(percentile(recent, 99)) if recent else None,
                             _num(lat.percentile(50)) if lat.n else None))
        self.version += 1

    def _recent_poses(self) -> list[float]:
        recent: list[float] = []
        for conn in self.hub.open.values():
            if conn.judge is not None:
                recent.extend(conn.judge._latencies[-200:])
        return recent

    def snapshot(self) -> dict[str, Any]:
        hub = self.hub
        requests, answers, poses = hub.counts()
        lat = hub.ctx.latency
        recent = self._recent_poses()
        s = hub.settings
        conns = []
        for number, conn in list(hub.open.items())[:SHOWN_CONNECTIONS]:
            r, a, p = judge_counts(conn.judge)
            conns.append({"number": number, "robot": conn.line.robot, "box": conn.line.box,
                          "transport": conn.line.transport, "role": _role(conn.judge),
                          "open_s": round(hub.clock() - conn.opened, 1), "requests": r, "answers": a, "poses": p,
                          "waiting": len(conn.judge.queue) if conn.judge is not None else 0})
        ring = hub.ring
        return {
            "version": self.version,
            "now": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime(hub.clock())),
            "elapsed_s": round(hub.elapsed(), 1),
            "listen": f"{s.listen[0]}:{s.listen[1]}", "upstream": f"{s.upstream[0]}:{s.upstream[1]}",
            "connections": {"open": len(hub.open), "total": hub.connections, "refused": hub.upstream_failures},
            "open": conns,
            "sessions": hub.ctx.stats.sessions,
            "frames": {"robot": requests, "box": answers, "poses": poses, "packets": hub.wire.frames},
            "rates": {"poses_per_s": round(self.pose_rate, 1), "frames_per_s": round(self.frame_rate, 1)},
            "latency_ms": {"command": {"n": lat.n, "p50": _num(lat.percentile(50)), "p99": _num(lat.percentile(99))},
                           "pose": {"n": hub.pose_latency.n,
                                    "p50": _num(percentile(recent, 50)) if recent else None,
                                    "p99": _num(percentile(recent, 99)) if recent else None}},
            "history": list(self.history),
            "alarms": [a.to_dict() for a in hub.alarms.all()[:SHOWN_ALARMS]],
            "alarms_active": len(hub.alarms.active),
            "findings": [c.to_dict() for c in hub.findings.roots.ordered()[:SHOWN_CAUSES]],
            "injected": hub.reactions.total,
            "ring": [{"file": p.name, "first_frame": first, "href": f"ring/{p.name}"}
                     for p, first in (ring.kept if ring is not None else ())],
            "reports": [{"file": name, "href": f"reports/{name}"} for name in REPORTS],
        }

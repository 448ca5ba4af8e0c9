"""Live alarms: what is wrong on the line *now*, not at the connection's close (sans-I/O).

The engine judges an unanswered request when its connection ends; a box that hangs at
02:00 with its connections open would be reported when someone stops the monitor.
:class:`Alarms` looks at the engine's state every tick (:meth:`Alarms.check`) and raises:

``box-silent`` (T1, box)
    the oldest request on a connection has waited ``time_out`` (``vision_time_out``
    for a result request, 27) without an answer. When the late answer arrives the
    alarm records it (the engine's T1 finding names the same request frame); when the
    queue moves on otherwise or the connection ends, it records that.
``stream-slow`` (T2, robot)
    a pose stream sent fewer poses per second than the declared rate allows
    (``--rate-tolerance``) over the last :data:`RATE_WINDOW_S` seconds (at least 20
    periods), for :data:`HOLD_S` (a stream that ends slows down for a moment before its
    connection closes); cleared when the rate is back.
``box-refused`` (S5, box)
    the box refused (or did not accept in ``--connect-timeout``) a connection the
    robot made; cleared by the next connection the box accepts.

Connections where the monitor injected a fault are not alarmed on from the fault on
(the monitor's own doing, as for findings). Each alarm is also counted by kind for the
metrics. At most :data:`KEEP` cleared alarms are kept.
"""

from __future__ import annotations

import time
from collections import deque
from dataclasses import dataclass, field
from typing import Any

from ..protocol import EXTENSION_ACTIONS, Action, action_name

__all__ = ["HOLD_S", "KINDS", "RATE_WINDOW_S", "Alarm", "Alarms"]

KINDS = ("box-silent", "stream-slow", "box-refused")
RATE_WINDOW_S = 2.0
HOLD_S = 1.0  # a stream below its rate this long raises stream-slow
KEEP = 200
MAX_ACTIVE = 1000


@dataclass
class Alarm:
    id: int
    kind: str
    clause: str
    side: str
    conn: int
    text: str
    raised: float
    frame: int | None = None
    cleared: float | None = None
    outcome: str = ""
    req: Any = field(default=None, repr=False, compare=False)  # the engine's queue entry (box-silent)

    @property
    def active(self) -> bool:
        return self.cleared is None

    def line(self) -> str:
        tail = f" — {self.outcome}" if self.outcome else ""
        return f"{self.side.upper()} {self.clause} [{self.kind}] {self.text}{tail}"

    def to_dict(self) -> dict[str, Any]:
        return {"id": self.id, "kind": self.kind, "clause": self.clause, "side": self.side, "connection": self.conn,
                "frame": self.frame, "what": self.text, "raised": _iso(self.raised),
                "cleared": _iso(self.cleared) if self.cleared is not None else None, "outcome": self.outcome,
                "active": self.active}


def _iso(t: float) -> str:
    return time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime(t)) + f".{int(t % 1 * 1000):03d}"


class Alarms:
    def __init__(self, time_out_ms: float, vision_time_out_ms: float, rate_hz: float, rate_tolerance: float) -> None:
        self.time_out_ms = time_out_ms
        self.vision_time_out_ms = vision_time_out_ms
        self.min_rate = rate_hz * (1.0 - rate_tolerance)
        self.rate_hz = rate_hz
        self.window_s = max(RATE_WINDOW_S, 20.0 / rate_hz) if rate_hz > 0 else RATE_WINDOW_S
        self.active: dict[tuple[str, int], Alarm] = {}
        self.cleared: deque[Alarm] = deque(maxlen=KEEP)
        self.raised = dict.fromkeys(KINDS, 0)
        self.samples: dict[int, deque[tuple[float, int]]] = {}  # stream connection -> (t, poses so far)
        self.below: dict[int, float] = {}  # stream connection -> since when its rate is below the bound
        self.next_id = 1
        self.changed: list[Alarm] = []  # raised or cleared since the last look (the view prints them)

    # -- raising and clearing -----------------------------------------------------------------------
    def _raise(self, kind: str, clause: str, side: str, conn: int, text: str, now: float,
               frame: int | None = None, req: Any = None) -> Alarm | None:
        key = (kind, conn)
        if key in self.active or len(self.active) >= MAX_ACTIVE:
            return None
        alarm = Alarm(self.next_id, kind, clause, side, conn, text, now, frame, req=req)
        self.next_id += 1
        self.active[key] = alarm
        self.raised[kind] += 1
        self.changed.append(alarm)
        return alarm

    def _clear(self, key: tuple[str, int], now: float, outcome: str) -> None:
        alarm = self.active.pop(key, None)
        if alarm is None:
            return
        alarm.cleared = now
        alarm.outcome = alarm.outcome or outcome
        alarm.req = None
        self.cleared.append(alarm)
        self.changed.append(alarm)

    def take_changes(self) -> list[Alarm]:
        out, self.changed = self.changed, []
        return out

    def by_kind(self) -> dict[str, int]:
        counts = dict.fromkeys(KINDS, 0)
        for kind, _conn in self.active:
            counts[kind] += 1
        return counts

    def all(self) -> list[Alarm]:
        """Active alarms first (oldest first), then the cleared ones (newest first)."""
        return sorted(self.active.values(), key=lambda a: a.raised) + list(reversed(self.cleared))

    # -- the box's connections ---------------------------------------------------------------------
    def refused(self, conn: int, text: str, now: float) -> None:
        self._raise("box-refused", "S5", "box", 0, f"connection {conn}: {text}", now)

    def accepted(self, conn: int, now: float) -> None:
        self._clear(("box-refused", 0), now, f"the box accepted connection {conn}")

    # -- the engine's findings ---------------------------------------------------------------------
    def finding(self, clause: str, side: str, text: str, frames: tuple[int, ...], now: float) -> None:
        """The engine filed a finding: a late answer (T1, naming the request's frame) ends its alarm."""
        if clause != "T1" or side != "box" or not frames:
            return
        for key, alarm in list(self.active.items()):
            if alarm.kind == "box-silent" and alarm.frame == frames[0]:
                self._clear(key, now, f"answered late: {text}")
                return

    # -- each tick -----------------------------------------------------------------------------------
    def check(self, conns: list[tuple[int, Any, bool]], now: float, faulted: dict[int, tuple[int, int]]) -> None:
        """``conns``: (connection number, the engine's judge or None, open?) of the connections to look at."""
        seen: set[int] = set()
        for number, judge, is_open in conns:
            if judge is None or not is_open:
                continue
            seen.add(number)
            fault = faulted.get(number)
            self._silent(number, judge, now, fault[0] if fault is not None else None)
            self._rate(number, judge, now)
        for key in [k for k in self.active if k[1] and k[1] not in seen]:
            self._clear(key, now, "the connection ended without the answer" if key[0] == "box-silent"
                        else "the stream connection closed")
        for number in [n for n in self.samples if n not in seen]:
            del self.samples[number]
            self.below.pop(number, None)

    def _silent(self, number: int, judge: Any, now: float, fault_frame: int | None) -> None:
        key = ("box-silent", number)
        alarm = self.active.get(key)
        queue = judge.queue
        head = queue[0] if queue and judge.desync is None else None
        if alarm is not None and head is not alarm.req:
            waited = (now - alarm.req[0]) * 1000.0 if alarm.req is not None else 0.0
            why = judge.desync or "the box answered a later request (this one may legally go unanswered)"
            self._clear(key, now, f"no longer awaited after about {waited:.0f} ms: {why}")
            alarm = None
        if head is None or alarm is not None:
            return
        t_req, action, _first, last = head[:4]
        if fault_frame is not None and last >= fault_frame:
            return  # the monitor's own fault delays it
        limit = self.vision_time_out_ms if action == Action.VISION_RESULT else self.time_out_ms
        waited = (now - t_req) * 1000.0
        if waited >= limit:
            label = judge.label
            legal = (" (a box without the extension E may stay silent on it: the robot's session stops here)"
                     if action in EXTENSION_ACTIONS else "")
            self._raise("box-silent", "T1", "box", number,
                        f"{label}: no answer to {action_name(action)} (frame {last}) for {waited:.0f} ms; "
                        f"the bound is {limit:.0f} ms (box silent, connection still open){legal}", now, last, head)

    def _rate(self, number: int, judge: Any, now: float) -> None:
        if judge.robot_counts or not judge.poses or self.rate_hz <= 0:
            self.samples.pop(number, None)
            return  # not a stream connection (yet)
        samples = self.samples.get(number)
        if samples is None:
            samples = self.samples[number] = deque(maxlen=256)
        samples.append((now, judge.poses))
        while len(samples) > 2 and now - samples[1][0] >= self.window_s:
            samples.popleft()
        t0, n0 = samples[0]
        span = now - t0
        key = ("stream-slow", number)
        if span < self.window_s:
            return
        rate = (judge.poses - n0) / span
        if rate >= self.min_rate:
            self.below.pop(number, None)
        elif now - self.below.setdefault(number, now) < HOLD_S:
            return  # not yet: a stream that ends slows down for a moment before its connection closes
        if rate < self.min_rate:
            self._raise("stream-slow", "T2", "robot", number,
                        f"{judge.label}: {rate:.1f} poses/s over the last {span:.1f} s; the declared "
                        f"{self.rate_hz:g} Hz allows no less than {self.min_rate:.1f}", now)
        elif key in self.active:
            self._clear(key, now, f"the stream is back at {rate:.1f} poses/s")

"""What the robot did after each injected fault (INFORMATIONAL, with timings; sans-I/O).

Every injection is an :class:`Injection`: which spec, on which connection, which answer,
when, and the frame that carries its pcap comment. For a while after it (until the robot
has both sent a request and the window of ``2 * time_out + 5 s`` has passed, or the
window ends) the robot's next moves are written down with their delay after the
fault: a request on the same connection (``sent CYCLE_ON again`` when it is the faulted
action, else ``carried on with POSE``), a close or reset of that connection, a new
connection from the robot's address (``reconnected``). The summary line compares a
close or a resend with the robot's ``time_out`` ("waited until its time_out").

Bounded: the first :data:`DETAILED` injections of each spec are followed; the rest are counted.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

from ..protocol import Profile, action_name

__all__ = ["DETAILED", "Injection", "Reactions"]

DETAILED = 20
MOVES = 6  # moves written down per injection


@dataclass
class Injection:
    id: int
    spec: str
    kind: str
    clause: str
    line: int
    robot_host: str
    action: int
    t: float
    frame: int
    what: str  # "CYCLE_ON answer held 6000 ms"
    moves: list[tuple[float, str]] = field(default_factory=list)  # (ms after the fault, what the robot did)
    requested: bool = False
    done: bool = False

    def summary(self, time_out_ms: float) -> str:
        if not self.moves:
            return "the robot did nothing the monitor saw afterwards"
        parts = []
        for ms, what in self.moves:
            text = f"{what} after {ms:.0f} ms"
            if ("closed" in what or "again" in what or "reset" in what) and abs(ms - time_out_ms) <= max(
                    50.0, 0.1 * time_out_ms):
                text += f" (its time_out, {time_out_ms:.0f} ms)"
            parts.append(text)
        return "; then ".join(parts)

    def to_dict(self, time_out_ms: float) -> dict[str, object]:
        return {"id": self.id, "spec": self.spec, "kind": self.kind, "clause": self.clause, "connection": self.line,
                "action": action_name(self.action), "frame": self.frame, "what": self.what,
                "robot": [{"after_ms": round(ms, 1), "did": what} for ms, what in self.moves],
                "summary": self.summary(time_out_ms)}


class Reactions:
    def __init__(self, profile: Profile) -> None:
        self.time_out_ms = profile.time_out_ms
        self.window_s = 2 * profile.time_out_s + 5.0
        self.injections: list[Injection] = []
        self.per_spec: dict[str, int] = {}
        self.total = 0
        self._watching: list[Injection] = []

    def injected(self, spec: str, kind: str, clause: str, line: int, robot_host: str, action: int, t: float,
                 frame: int, what: str) -> Injection:
        self.total += 1
        inj = Injection(self.total, spec, kind, clause, line, robot_host, action, t, frame, what)
        n = self.per_spec.get(spec, 0)
        self.per_spec[spec] = n + 1
        if n < DETAILED:
            self.injections.append(inj)
            self._watching.append(inj)
        return inj

    def _record(self, t: float, what: str | Callable[[Injection], str], mine: Callable[[Injection], bool],
                request: bool = False) -> None:
        """A move of the robot at ``t``, for every injection it concerns (``mine(injection)``)."""
        for inj in self._watching:
            if t < inj.t or not mine(inj):
                continue
            if t - inj.t > self.window_s:
                inj.done = True
                continue
            inj.moves.append(((t - inj.t) * 1000.0, what(inj) if callable(what) else what))
            inj.requested = inj.requested or request
            inj.done = len(inj.moves) >= MOVES
        self._watching = [i for i in self._watching if not i.done]

    def request(self, line: int, action: int, t: float) -> None:
        for inj in self._watching:
            if inj.line == line and inj.requested and action == 0x23:
                inj.done = True  # the stream goes on: its poses say nothing more
        self._watching = [i for i in self._watching if not i.done]
        self._record(t, lambda inj: (f"sent {action_name(action)} again" if action == inj.action
                                     else f"carried on with {action_name(action)}"),
                     lambda inj: inj.line == line, request=True)

    def closed(self, line: int, reset: bool, t: float) -> None:
        self._record(t, "reset the connection" if reset else "closed the connection", lambda inj: inj.line == line)

    def connected(self, host: str, t: float) -> None:
        self._record(t, "reconnected", lambda inj: inj.robot_host == host)

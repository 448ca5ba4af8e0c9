"""The engine's findings, as they happen: told to the view, excused when a fault caused them, deduplicated.

:class:`LiveFindings` is ``analyze``'s :class:`~conformance.analyze.findings.Findings`
(the same tallies, so the same reports) with three additions:

* every finding that is not PASS is handed to ``on_finding`` as it is filed (the
  terminal prints it);
* a finding on a connection where the monitor injected a fault, from the request whose
  answer it changed on, is the monitor's doing (the box's) or the robot's reaction to it
  (INFORMATIONAL, the robot's): it is not filed but kept with the fault (:attr:`excused`).
  A frame-format finding is the box's unless the monitor corrupted that very frame, and
  always the robot's for its own frames;
* findings are grouped into root causes (:class:`RootCauses`): the side, the clause, the
  verdict and the finding's text with its numbers and addresses taken out, each with a
  count and when it was first and last seen. At most :data:`MAX_CAUSES` groups are kept;
  past that, the rest of a (side, clause, verdict) is counted in one "other" group.
"""

from __future__ import annotations

import re
import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass

from ..analyze.findings import BOX, Findings, Observation
from ..model.verdicts import Verdict

__all__ = ["MAX_CAUSES", "Cause", "LiveFindings", "RootCauses", "signature"]

MAX_CAUSES = 200
KEEP_EXCUSED = 50  # findings kept per injection
MAX_FAULTED = 10_000  # faulted connections (and injections with findings kept) remembered
_CONN = re.compile(r"\b(conn|udp) (\d+) \([^)]*\)")
#: the clauses of a frame's format: a finding of these is excused only for a frame the monitor wrote
FORMAT = frozenset({"F1", "F2", "F3", "F4", "F5", "F6", "F7", "B1", "B2", "B3", "B4", "B5", "E1", "A4"})
_NUMBER = re.compile(r"\d+(?:[.,]\d+)*")


def signature(text: str) -> str:
    """The finding's text without its connection, numbers and hex: what stays the same each time."""
    return _NUMBER.sub("N", _CONN.sub(r"\1", text))


@dataclass
class Cause:
    side: str
    clause: str
    verdict: Verdict
    signature: str
    first: Observation
    first_seen: float
    last_seen: float
    count: int = 1

    def to_dict(self) -> dict[str, object]:
        return {"side": self.side, "clause": self.clause, "verdict": self.verdict.value, "what": self.signature,
                "count": self.count, "first_seen": _iso(self.first_seen), "last_seen": _iso(self.last_seen),
                "first": self.first.line(), "robot_hex": self.first.robot_hex[:200], "box_hex": self.first.box_hex[:200]}


def _iso(t: float) -> str:
    return time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime(t)) + f".{int(t % 1 * 1000):03d}"


class RootCauses:
    def __init__(self) -> None:
        self.causes: dict[tuple[str, str, Verdict, str], Cause] = {}

    def add(self, side: str, clause: str, finding: Observation, t: float) -> Cause:
        sig = signature(finding.text)
        key = (side, clause, finding.verdict, sig)
        cause = self.causes.get(key)
        if cause is None and len(self.causes) >= MAX_CAUSES:
            key = (side, clause, finding.verdict, "other findings of this clause (the list of root causes is full)")
            cause = self.causes.get(key)
        if cause is None:
            cause = self.causes[key] = Cause(side, clause, finding.verdict, key[3], finding, t, t, 0)
        cause.count += 1
        cause.last_seen = t
        return cause

    def ordered(self) -> list[Cause]:
        """Worst first (FAIL before NON-STRICT ...), then the most frequent."""
        from ..model.verdicts import VERDICT_ORDER

        rank = {v: i for i, v in enumerate(VERDICT_ORDER)}
        return sorted(self.causes.values(), key=lambda c: (rank.get(c.verdict, 99), -c.count, c.first_seen))


class LiveFindings(Findings):
    def __init__(self, on_finding: Callable[[str, str, Observation, Cause], None] | None = None,
                 clock: Callable[[], float] = time.time) -> None:
        super().__init__()
        self.on_finding = on_finding
        self.clock = clock
        self.roots = RootCauses()
        #: engine connection number -> (first frame of the injected fault, the fault's event id)
        self.faulted: dict[int, tuple[int, int]] = {}
        self.excused: dict[int, list[str]] = {}  # fault event id -> the box findings it caused (bounded)
        self.excused_count = 0
        self.corrupted: dict[int, int] = {}  # frame the monitor wrote corrupted -> the fault's event id (bounded)

    def fault_on(self, conn: int, frame: int, event: int, written: int | None = None) -> None:
        """A fault was injected on connection ``conn`` from ``frame`` on (the request whose answer it
        changed): both sides' later pairing, timing and content findings there are the fault's; the box's
        format findings only for the frame the monitor ``written`` (a corrupted answer)."""
        if conn not in self.faulted and len(self.faulted) >= MAX_FAULTED:
            del self.faulted[next(iter(self.faulted))]  # the connection faulted longest ago
        self.faulted.setdefault(conn, (frame, event))
        if written is not None and len(self.corrupted) < 100_000:
            self.corrupted[written] = event

    def _excuse(self, side: str, text: str, frames: tuple[int, ...]) -> int | None:
        if not self.faulted:
            return None
        m = _CONN.search(text)
        entry = self.faulted.get(int(m.group(2))) if m else None
        if entry is None or (frames and max(frames) < entry[0]):
            return None
        return entry[1]

    def _excuse_format(self, side: str, text: str, frames: tuple[int, ...]) -> int | None:
        """A malformed answer is the monitor's only when it is a frame the monitor corrupted."""
        if side != BOX:
            return None
        return next((self.corrupted[f] for f in frames if f in self.corrupted), None)

    def add(self, clause: str, side: str, verdict: Verdict, text: str, frames: Iterable[int] = (),
            robot: bytes = b"", box: bytes = b"") -> None:
        frames = tuple(frames)
        event = self._excuse(side, text, frames) if clause not in FORMAT else self._excuse_format(side, text, frames)
        if event is not None and verdict is not Verdict.PASS:
            self.excused_count += 1
            kept = self.excused.get(event)
            if kept is None and len(self.excused) < MAX_FAULTED:
                kept = self.excused[event] = []
            if kept is not None and len(kept) < KEEP_EXCUSED:
                kept.append(f"{side} {clause} {verdict.value}: {Observation(verdict, text, frames).line()}")
            return
        super().add(clause, side, verdict, text, frames, robot, box)
        if verdict is Verdict.PASS:
            return
        finding = Observation(verdict, text, frames, robot[:64].hex(" "), box[:64].hex(" "))
        cause = self.roots.add(side, clause, finding, self.clock())
        if self.on_finding is not None:
            self.on_finding(clause, side, finding, cause)

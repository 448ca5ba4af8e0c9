"""Bounded time for a box that leaves well-formed requests unanswered in a pattern: what waits teach.

:mod:`.quiet` learns from the waits behind malformed input (the probe left unanswered, or
answered with an error and no 0000 behind it). This module learns from the plain waits
of :meth:`~conformance.harness.client.TcpConnection.request`: a well-formed request whose
answer did not come within time_out. The pattern is where on its connection it happened,
the number of answers the connection had carried before (a box that drops every Nth
answer, or goes quiet on a connection after N answers, leaves the same place unanswered in
every case that gets that far), a pose stream's overdue answer (:data:`STREAM`), the
answer to a later frame of one write whose first frames were answered (:data:`COALESCED`), or the answer to
bytes sent in pieces (:data:`SPLIT`).

A wait that ran out is *pending* until its case ends; it counts only when the case FAILed
on that silence (a :data:`~.signature.Sig.SILENCE` verdict: the answer was required, not
a legal silence). After :data:`REPEAT` cases, later requests at that place on a connection
first wait :data:`~.quiet.CUT_S`; unanswered by then, and the box still answering a fresh
connection, the case ends INCONCLUSIVE under that root cause (the silence's signature).
The pattern is withdrawn once the box answers a request at that place in time. What a
case saw before the cut stays judged; a FAIL is never turned into a PASS.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass, field

from .quiet import CUT_S

#: After this many cases FAILed on a silence at one place, later requests there are cut short.
REPEAT = 2
#: The place of a pose stream's overdue answer (any pose: a stream's answers are read as they come).
STREAM = -1
#: ... whose short wait is longer: a stream's answers may trail its poses (S6).
STREAM_CUT_S = 1.0
#: The place of the answer to a later frame of one write whose earlier frames were answered (R4: a box that
#: answers only the first frame of a read leaves this place unanswered in every case that pipelines).
COALESCED = -2
#: The place of the answer to bytes sent in pieces, the first one shorter than a header (R3: a box that loses a
#: frame whose header came in pieces leaves this place unanswered in every case that splits headers) ...
SPLIT = -3
#: ... and split after the first header.
SPLIT_BODY = -4
#: the place of bytes sent in pieces, by where the first piece ends (``TcpConnection.split_write``)
SPLIT_PLACES = {"header": SPLIT, "body": SPLIT_BODY}


@dataclass
class RanOut:
    """Per place (the answers a connection had carried before the request): the cases whose request there
    went unanswered for time_out, and FAILed on it."""

    cases: dict[int, list[str]] = field(default_factory=dict)
    answered: set[int] = field(default_factory=set)
    pending: dict[str, list[int]] = field(default_factory=dict)
    _lock: threading.Lock = field(default_factory=threading.Lock)

    def ran_out(self, case_id: str, place: int) -> None:
        """A wait at ``place`` ran out time_out in case ``case_id`` (counted if the case FAILs on it)."""
        with self._lock:
            self.pending.setdefault(case_id, []).append(place)

    def case_ended(self, case_id: str, failed_on_silence: bool, failed: bool = False) -> None:
        """Count the case's ran-out waits if it FAILed on a silence (a stream's: if it FAILed)."""
        with self._lock:
            places = self.pending.pop(case_id, [])
            for place in places:
                if failed_on_silence or (failed and place == STREAM):
                    seen = self.cases.setdefault(place, [])
                    if case_id not in seen:
                        seen.append(case_id)

    def answered_at(self, place: int) -> None:
        """A request at ``place`` was answered in time: the silences there had another cause."""
        with self._lock:
            self.answered.add(place)

    def known(self, place: int) -> list[str] | None:
        with self._lock:
            cases = self.cases.get(place, [])
            return list(cases) if len(cases) >= REPEAT and place not in self.answered else None

    def bound(self, place: int, time_out_s: float) -> float | None:
        """The short first wait for a request at ``place`` (None: wait in full)."""
        if self.known(place) is None:
            return None
        return min(STREAM_CUT_S if place in (STREAM, COALESCED, SPLIT, SPLIT_BODY) else CUT_S, time_out_s)

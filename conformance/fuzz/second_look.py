"""A probe left unanswered past time_out, looked at again before the silence is charged to the bytes (issue 34).

The oracle reads a probe unanswered for the whole time_out as a hang after bad bytes (NON-STRICT R6)
or a valid request left unanswered (T1). Two other stories fit the same silence, and
:func:`recheck` tells them apart before the verdict is kept:

* **the whole box stalled** (T1, S4): a fresh connection opened right after the silence is not
  answered promptly either, and both come back together (the probe in flight answered late too). The stall (when it began: after which
  bytes and how many writes of the campaign; how long it lasted; which connections it held) is
  recorded (:func:`take`) and reported once as its own root cause, never charged to the bytes
  in flight: their R6/T1 findings are dropped;
* **the box framed the bytes otherwise** (legal, R6 b): it took the probe's first bytes to
  complete a frame the bytes left short, and waits for the next header. A second probe on the
  same connection is answered: the hang finding is dropped.

Only when a second probe on the same connection also goes unanswered, while a fresh connection
is answered promptly, does NON-STRICT R6 stand. A fresh connection left silent for its whole
time_out is a death, not a stall: that is left to the liveness check (R2). Every wait is bounded
by time_out.
"""

from __future__ import annotations

import threading
import time
from dataclasses import dataclass, replace
from typing import Protocol

from ..harness.client import Answer, Closed, Malformed, Silence, TcpConnection
from ..harness.liveness import check_alive, responsive
from ..harness.target import Target
from ..harness.transcript import Kind, Transcript
from ..protocol import Profile
from .oracle import Judgement
from .strategies import FuzzCase


class Result(Protocol):
    """What :func:`recheck` reads of the executor's result of one case."""

    case: FuzzCase
    judgement: Judgement


@dataclass(frozen=True)
class Where:
    """The box and the campaign so far: whom a fresh connection asks, and the example's number."""

    transcript: Transcript
    target: Target
    profile: Profile
    time_out_s: float
    example: int

#: a fresh connection answered this late (seconds; at most a quarter of time_out) was held by the stall too
STALL_MIN_S = 0.5
#: the findings that charge a silence at the end to the bytes
SILENCE_KEYS = ("end/hang", "end/silence")

_STALLS: dict[tuple[str, int], list[BoxStall]] = {}
_LOCK = threading.Lock()


@dataclass(frozen=True)
class BoxStall:
    """A box-wide silence the box came back from."""

    after: str  # the bytes in flight when it began (hex, cut short)
    example: int  # the campaign's example number then
    writes: int  # writes the campaign had made to the box by then
    lasted_s: float  # from the write of those bytes to the first answer after the silence (at most this)
    affected: str  # who was held: the connection in flight, and a fresh one
    at_least: bool = False  # lasted_s is a lower bound (met by a liveness check: when it began is not known)

    def to_dict(self) -> dict[str, object]:
        return {"after": self.after, "example": self.example, "writes": self.writes,
                "lasted_s": round(self.lasted_s, 2), "affected": self.affected, "at_least": self.at_least}

    def describe(self) -> str:
        how = "at least" if self.at_least else "about"
        return (f"the whole box stalled for {how} {self.lasted_s:.1f} s, once: it began after the campaign's write "
                f"{self.writes} (example {self.example}: {self.after}); {self.affected}")


def take(target: tuple[str, int]) -> list[BoxStall]:
    """The stalls recorded against ``target`` since the last call (the FUZZ case reports them)."""
    with _LOCK:
        return _STALLS.pop(target, [])


def _record(target: tuple[str, int], stall: BoxStall) -> None:
    with _LOCK:
        _STALLS.setdefault(target, []).append(stall)


def _writes(transcript: Transcript) -> int:
    return sum(1 for e in transcript.events if e.kind == Kind.SEND)


def recheck(where: Where, conn: TcpConnection, result: Result, probe: bytes, sent_at: float) -> None:
    """The probe behind ``result``'s bytes went unanswered (``result.end`` is a Silence): a fresh connection, then
    (when that is answered promptly) a second probe on ``conn``; ``result``'s findings kept, dropped or annotated."""
    keys = [f for f in result.judgement.findings if f.key in SILENCE_KEYS]
    if not keys:
        return
    time_out = where.time_out_s
    fresh_at = time.monotonic()
    fresh = check_alive(where.transcript, where.target, where.profile, time_out_s=time_out,
                        label="fuzz: fresh connection during the silence", note="a NONE on a fresh connection: is "
                        "the whole box silent?")
    if isinstance(fresh, Silence) or not responsive(fresh):
        return  # a death (or a close): the liveness check judges it (R2)
    held_s = fresh.latency_s
    late = [o for o in conn.drain(min(STALL_MIN_S, time_out)) if isinstance(o, (Answer, Malformed))]
    if late and held_s >= min(STALL_MIN_S, time_out / 4):  # both came back together: the whole box was silent
        who = ("the connection in flight (its probe answered only after the silence) and a fresh connection opened "
               f"during the silence (answered after {held_s * 1000:.0f} ms)")
        _record((where.target.host, where.target.port), BoxStall(
            result.case.wire[:16].hex(" ") + (" …" if len(result.case.wire) > 16 else ""),
            where.example, _writes(where.transcript), fresh_at + held_s - sent_at, who))
        _drop(result)
        return
    if late:  # the probe's own answer came late while a fresh connection was answered at once: not a stall
        return
    second = conn.send(probe, "fuzz: a second probe on the same connection: does the box answer it?")
    again = conn.next_outcome(time_out) if second else Closed(True, 0.0)
    if isinstance(again, (Answer, Malformed)):
        _drop(result, keys=("end/hang",))  # it took the first probe's bytes to complete a frame: legal framing
        return
    result.judgement.findings[:] = [
        replace(f, observed=f.observed + "; a second probe on the same connection went unanswered too, while a "
                "fresh connection was answered") if f.key == "end/hang" else f for f in result.judgement.findings]


def stall_not_death(where: Where, restarted: bool, confirmed: bool, back: bool, last: bytes) -> bool:
    """A liveness check met the silence first: the campaign's death search ended with the box back on its own
    (no restart) and no case stopping it again. Then the whole box stalled: recorded (True), no death reported."""
    if restarted or confirmed or not back:
        return False
    after = last[:16].hex(" ") + (" …" if len(last) > 16 else "") if last else "the campaign's start"
    _record((where.target.host, where.target.port), BoxStall(
        after, where.example, _writes(where.transcript), where.time_out_s,
        "a fresh connection (the liveness check) went unanswered for time_out; the box then answered again "
        "without a restart, and no case replayed stopped it again", at_least=True))
    return True


def _drop(result: Result, keys: tuple[str, ...] = SILENCE_KEYS) -> None:
    result.judgement.findings[:] = [f for f in result.judgement.findings if f.key not in keys]


__all__ = ["BoxStall", "recheck", "stall_not_death", "take"]

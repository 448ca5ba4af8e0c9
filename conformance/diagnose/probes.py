"""Exchanges the :class:`~.experiments.Prober` does not make: a frame in pieces over time, two connections at
once, many requests on one connection with their latencies. Each on fresh connections, every wait bounded by
the prober's deadline, nothing the box does raised out of here; each is recorded as an
:class:`~.hypotheses.Exchange` in the experiment given."""

from __future__ import annotations

import time
from collections.abc import Sequence

from ..harness.client import Answer, Closed, Malformed, Silence, TcpConnection
from ..harness.target import Unreachable
from .experiments import MIN_LEFT_S, QUIET_S, Prober, heard
from .hypotheses import Exchange, Experiment, Reading

#: the gap between the pieces of a split frame (R3: pieces over time)
GAP_S = 0.05
#: an exchange that ended this close to the deadline may have had a wait cut short by it
CUT_S = 0.05


def full_wait(p: Prober, frames: int = 1, gaps_s: float = 0.0) -> bool:
    """Whether the deadline leaves room for ``frames`` frames (the last waited for a whole time_out, the others a
    quiet wait) and ``gaps_s`` of pauses: a silence cut short by the deadline is no finding."""
    return p.left() >= p.dialer.time_out_s + QUIET_S * (frames - 1) + gaps_s + MIN_LEFT_S


def cut_short(p: Prober) -> bool:
    """After an exchange: whether a wait may have been cut by the deadline (a cut wait ends at it)."""
    return p.left() < CUT_S


def _connect(p: Prober) -> TcpConnection | None:
    if p.left() < MIN_LEFT_S:
        return None
    p.count += 1
    try:
        conn = p.dialer.dial("diagnose")
    except Unreachable as exc:
        p.unreachable = str(exc)
        return None
    return conn


def _one(p: Prober, conn: TcpConnection, wait_s: float | None = None) -> Reading:
    outcome = conn.next_outcome(max(0.0, min(p.dialer.time_out_s if wait_s is None else wait_s, p.left())))
    if isinstance(outcome, Silence):
        return Reading()
    if isinstance(outcome, Closed):
        return Reading((), True)
    assert isinstance(outcome, (Answer, Malformed))
    return Reading((heard(outcome),))


def in_pieces(p: Prober, exp: Experiment, frame: bytes, cuts: Sequence[int], gap_s: float = GAP_S) -> Reading | None:
    """``frame`` cut at ``cuts`` and sent piece by piece ``gap_s`` apart, on a fresh connection."""
    if not full_wait(p, 1, gap_s * len(cuts)):
        return None
    conn = _connect(p)
    if conn is None:
        return None
    try:
        bounds = [0, *cuts, len(frame)]
        pieces = [frame[a:b] for a, b in zip(bounds, bounds[1:]) if b > a]
        reading = Reading((), True) if not conn.send_pieces(pieces, gap_s, "diagnose") else _one(p, conn)
    finally:
        conn.close("diagnose")
    exp.exchanges.append(Exchange((frame,), (reading,)))
    return reading


def beside(p: Prober, exp: Experiment, first: Sequence[bytes], frame: bytes) -> tuple[Reading, Reading] | None:
    """``first`` on connection A (each answered), then ``frame`` on a second connection B while A is open, then
    ``frame`` on A: (B's reading, A's reading)."""
    if not full_wait(p, 3):
        return None
    a = _connect(p)
    if a is None:
        return None
    b = None
    try:
        for f in first:
            if not a.send(f, "diagnose") or _one(p, a).closed:
                return None
        b = _connect(p)
        if b is None:
            return None
        other = Reading((), True) if not b.send(frame, "diagnose") else _one(p, b)
        same = Reading((), True) if not a.send(frame, "diagnose") else _one(p, a)
    finally:
        a.close("diagnose")
        if b is not None:
            b.close("diagnose")
    exp.exchanges.append(Exchange((*first, frame), (other, same)))
    return other, same


def latencies(p: Prober, exp: Experiment, frame: bytes, n: int) -> list[float]:
    """``frame`` sent ``n`` times on one connection, each after the last was answered: each answer's latency in
    ms (stops at the first silence or close, or at the deadline)."""
    conn = _connect(p)
    out: list[float] = []
    if conn is None:
        return out
    try:
        for _ in range(n):
            if p.left() < MIN_LEFT_S:
                break
            t0 = time.monotonic()
            if not conn.send(frame, "diagnose"):
                break
            reading = _one(p, conn)
            if not reading.answers:
                break
            out.append((time.monotonic() - t0) * 1000.0)
    finally:
        conn.close("diagnose")
    return out

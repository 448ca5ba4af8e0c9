"""S6/R4/A1 under backpressure: the robot reads late or in small pieces, and the box keeps every answer.

Every other case reads its answers promptly, so the box's send buffer never fills. Here
the suite's receive buffer is small (``SO_RCVBUF``) and it reads late: a stream read after
time_out, a burst of thousands of pipelined poses read only when the suite could not
send, and the same burst read in random pieces of 1 to 24 bytes. A box that drops what a
short ``send()`` did not write cuts frames (F5) and loses answers (S6, A1).
"""

from __future__ import annotations

import random

from conformance.harness.client import TcpConnection
from conformance.protocol import Action, encode, pose_blocks, request
from conformance.suite import CaseContext, Inconclusive, Level, Requirement, Sig, Signature, case, responsive
from conformance.suite.backpressure import (
    ANSWER_LEN,
    BUDGET_S,
    PACE_REQUESTS,
    Backlog,
    burst,
    burst_size,
    judge_answers,
    late_stream,
    pace,
    small_rcvbuf,
)
from conformance.suite.sequence import DEFAULT_POSE
from conformance.suite.waits import STREAM

#: how many poses a burst pipelines (each answer 14 bytes: about 40 KB of answers behind a 2 KB window); fewer
#: when the box's pace (suite.backpressure.pace) would take more than a few seconds to answer them
BURST = 3000
#: one root cause for the backpressure verdicts: answers the box never delivered whole once the robot read late
LOST = Signature(Sig.SILENCE, "every POSE when the robot reads late (S6)")
CHECKS = {"F5": Requirement(("F5", "S6"), "every answer the box writes is a whole frame, however late the robot reads"),
          "A1": Requirement(("A1", "S6"), "one answer per request, in request order, each 0000"),
          "S6": Requirement(("S6", "A1"), "the box keeps every answer however late the robot reads them")}


def _connect(isight: CaseContext, label: str) -> TcpConnection:
    return isight.connect(label, target=isight.session.stream_target(), prepare=small_rcvbuf)


def _pose(isight: CaseContext) -> bytes:
    return encode(request(Action.POSE, pose_blocks([DEFAULT_POSE], isight.profile.first_index)), isight.profile)


#: why a wait was cut short (suite.waits): streams, or several requests in one write, of earlier FAILed cases
STREAMS_LEFT = "streams of earlier cases left a pose unanswered for the whole time_out"
WRITES_LEFT = "earlier cases' requests sent several in one write were left unanswered after the first (R4)"


def _quiet_s(isight: CaseContext, conn: TcpConnection, one_write: bool = False) -> tuple[float, str]:
    """How long to wait for answers still due, and why it is short: time_out, or 1 s once two FAILed cases left a
    stream's pose unanswered for the whole time_out, or (``one_write``: a burst) a later frame of one write."""
    if one_write and conn.coalesced_bound is not None and conn.coalesced_bound < isight.time_out_s:
        return conn.coalesced_bound, WRITES_LEFT
    if conn.stream_bound is not None and conn.stream_bound < isight.time_out_s:
        return conn.stream_bound, STREAMS_LEFT
    return isight.time_out_s, ""


def _judge(isight: CaseContext, conn: TcpConnection, out: Backlog, what: str, quiet: tuple[float, str]) -> None:
    quiet_s, why = quiet
    isight.details[what] = {"requests": out.requests, "sent_bytes": out.sent_bytes, "received_bytes": len(out.received),
                            "reads": out.reads, "unread_s": round(out.unread_s, 3), "elapsed_s": round(out.elapsed_s, 3),
                            "pace_hz": round(out.pace_hz, 1), "ended": out.ended or "normally"}
    bad = judge_answers(out, int(Action.POSE), out.requests)
    if bad is None and out.ended == "budget":
        raise Inconclusive(f"{what}: {len(out.received) // ANSWER_LEN} of {out.requests} answers read in "
                           f"{BUDGET_S:.0f} s, every one intact and in order, and more still coming: too slow to wait "
                           "for in bounded time, so the rest were not judged", judged=("S6",))
    if bad is not None and out.ended == "silent" and quiet_s < isight.time_out_s:
        isight.close_all()
        if responsive(isight.check_alive()):
            seen = bad.observed.replace("; then nothing more came for time_out", "")
            raise Inconclusive(f"{what}: {seen}, nothing more within {quiet_s * 1000:.0f} ms; {why} (the box still "
                               "answers a fresh connection), so the wait ended there, not judged", signature=LOST,
                               judged=("S6",))
    if bad is not None and out.ended == "silent" and conn.on_ran_out is not None:
        conn.on_ran_out(STREAM)  # a stream left unanswered for time_out: the pattern counts if this case FAILs
    if bad is not None:
        raise isight.broken(bad.clause, expected=bad.expected, observed=f"{what}: {bad.observed}",
                            received=bad.received, sent=_pose(isight), signature=LOST)


@case("S6-02", ["S6", "A1", "F5", "T2"], Level.MUST, "A stream read late: every answer kept, intact and in order",
      "poses at the profile rate for time_out with nothing read (the suite's receive buffer small), then everything "
      "read: one intact 0000 answer per pose, in order", checks=CHECKS)
def test_stream_read_late(isight: CaseContext) -> None:
    conn = _connect(isight, "stream (read late)")
    pose = _pose(isight)
    quiet = _quiet_s(isight, conn)
    out = late_stream(conn, lambda i: pose, isight.profile.pose_rate_hz, isight.time_out_s, ANSWER_LEN,
                      isight.time_out_s, "stream read late", quiet[0])
    _judge(isight, conn, out, "stream read late", quiet)


@case("S6-03", ["S6", "R4", "A1", "F5"], Level.MUST, "A burst of pipelined poses behind a small receive window",
      f"a pace probe of {PACE_REQUESTS} poses, then {BURST} (fewer from a box too slow to answer them in seconds) sent "
      "back to back, the suite reading only when it cannot send (its receive buffer small, so the box's send buffer "
      "fills): one intact 0000 answer per pose, in order", checks=CHECKS)
def test_burst(isight: CaseContext) -> None:
    conn = _connect(isight, "stream (burst)")
    quiet = _quiet_s(isight, conn, one_write=True)
    out = _burst(isight, conn, quiet[0], None, "burst")
    _judge(isight, conn, out, "burst", quiet)


@case("S6-04", ["S6", "R4", "A1", "F5"], Level.MUST, "The burst read in random small pieces",
      f"the pace probe, then {BURST} poses (fewer from a slow box) sent back to back, the answers read in random "
      "pieces of 1 to 24 bytes (receive buffer small): "
      "one intact 0000 answer per pose, in order", checks=CHECKS)
def test_split_reads(isight: CaseContext) -> None:
    conn = _connect(isight, "stream (split reads)")
    quiet = _quiet_s(isight, conn, one_write=True)
    out = _burst(isight, conn, quiet[0], random.Random(isight.settings.seed), "burst, split reads")
    _judge(isight, conn, out, "split reads", quiet)


def _burst(isight: CaseContext, conn: TcpConnection, quiet: float, rng: random.Random | None, note: str) -> Backlog:
    """The pace probe, then the burst sized to it (BURST poses from a box that answers them in a few seconds)."""
    pose = _pose(isight)
    out = pace(conn, pose, ANSWER_LEN, quiet, note)
    if out.ended:
        return out
    size = burst_size(out.pace_hz, BURST)
    return burst(conn, [pose] * size, (out.requests + size) * ANSWER_LEN, isight.time_out_s, rng, note, quiet, out)

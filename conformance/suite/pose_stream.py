"""The background pose stream (S6, T2): poses on a fixed clock, answers matched in order.

:class:`PoseStream` sends poses from a background thread and matches the pipelined
answers in order (A1); :class:`StreamResult` is what it saw and :func:`judge_stream`
the verdict on it. :func:`percentile` and :func:`latency_figures` summarise latencies.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from ..harness.client import Answer, Malformed, Outcome, Silence, TcpConnection
from ..harness.liveness import check_alive, responsive
from ..harness.starvation import gauge, starved_share, starved_text
from ..harness.trajectory import PrimerTrajectory
from ..harness.waits import STREAM
from ..model.percentiles import percentile
from ..model.signature import Sig, Signature
from ..model.verdicts import Level
from ..protocol import Action, request
from .case_judge import Expect, Inconclusive, answered, check, fail

DEFAULT_POSE = PrimerTrajectory().home


def latency_figures(values: list[float]) -> dict[str, Any]:
    if not values:
        return {"count": 0}
    return {"count": len(values), "p50_ms": round(percentile(values, 50), 3), "p90_ms": round(percentile(values, 90), 3),
            "p99_ms": round(percentile(values, 99), 3), "max_ms": round(max(values), 3)}


# -- the pose stream (S6, T2) -----------------------------------------------------------------------


@dataclass
class StreamResult:
    """What a pose stream saw: answers matched to poses in order, and how it ended."""

    rate_hz: float
    time_out_s: float = 5.0
    sent: int = 0
    answered: int = 0
    latencies_ms: list[float] = field(default_factory=list)
    bad: Outcome | None = None  # the first answer that did not match the expectation
    bad_index: int = -1
    bad_sent: bytes = b""
    extra: int = 0  # answers beyond the poses sent (A1)
    ended: str = ""  # "", "closed", "reset", "malformed", "overdue", "blocked": why the stream stopped early
    ended_by: Outcome | None = None
    max_send_lag_ms: float = 0.0
    elapsed_s: float = 0.0
    started_at: float = 0.0  # monotonic: for the starvation gauge's stalls over the stream
    cut_s: float = 0.0  # the overdue answer was awaited only this long (bounded time: harness.waits), the box alive
    sent_at: list[float] = field(default_factory=list)  # monotonic send time of each pose

    @property
    def lost(self) -> int:
        return self.sent - self.answered

    @property
    def failed(self) -> bool:
        return bool(self.ended) or self.bad is not None or self.extra > 0

    def backlog(self) -> tuple[float, float, float] | None:
        """(first-quarter p50, last-quarter p50, threshold) in ms; None with fewer than 8 answers.

        T2 backlog: the last quarter's p50 above first p50 + max(20 ms, first p50), i.e. above both twice the
        first quarter's and 20 ms more. (It was + max(20 ms, 3 × first p50): a box whose latency grows 2 ms a pose
        from a base of 100 ms then passed, its first quarter alone setting a bar of 550 ms.)"""
        n = len(self.latencies_ms) // 4
        if n < 2:
            return None
        first, last = percentile(self.latencies_ms[:n], 50), percentile(self.latencies_ms[-n:], 50)
        return first, last, first + max(20.0, first)

    def figures(self) -> dict[str, Any]:
        out = {"rate_hz": self.rate_hz, "sent": self.sent, "answered": self.answered, "lost": self.lost,
               "extra_answers": self.extra, "ended": self.ended or "normally", "elapsed_s": round(self.elapsed_s, 3),
               "max_send_lag_ms": round(self.max_send_lag_ms, 3), "latency": latency_figures(self.latencies_ms)}
        b = self.backlog()
        if b is not None:
            out["backlog"] = {"first_quarter_p50_ms": round(b[0], 3), "last_quarter_p50_ms": round(b[1], 3),
                              "threshold_ms": round(b[2], 3)}
        return out


def trajectory_poses(kind: Any, rate_hz: float, duration_s: float | None) -> Callable[[int], tuple[float, ...]]:
    """Pose number i of a stream: along the primer trajectory, fixed, or cycling through a given list."""
    if isinstance(kind, list):
        return lambda i: tuple(kind[i % len(kind)])
    if kind == "fixed":
        return lambda i: DEFAULT_POSE
    path = PrimerTrajectory(duration=max(0.5, duration_s or 2.0))
    return lambda i: path.pose_at((i / rate_hz) % path.duration)


class PoseStream:
    """Poses on a fixed clock from a background thread, answers read as they come (pipelined).

    Send times come from a monotonic schedule (``t0 + i/rate``), not from sleeps, so
    they do not drift. One thread both sends and reads, so the connection is never
    shared; the answer k is matched to pose k (A1: in order). The stream ends after
    ``duration_s`` (None: until :meth:`stop`), or early when the box closes, sends
    malformed bytes, or leaves a pose unanswered for longer than ``time_out_s``.
    """

    def __init__(self, conn: TcpConnection, rate_hz: float, duration_s: float | None, time_out_s: float,
                 poses: Callable[[int], tuple[float, ...]] | None = None, expect: Expect | None = None) -> None:
        self.conn, self.rate_hz, self.duration_s, self.time_out_s = conn, rate_hz, duration_s, time_out_s
        self.poses = poses or trajectory_poses("primer", rate_hz, duration_s)
        self.expect = expect or answered(Action.POSE, [0])
        self.result = StreamResult(rate_hz, time_out_s)
        self._sent_at: list[float] = self.result.sent_at
        self._frames: list[bytes] = []
        self._stop = threading.Event()
        self._stopped_gauge = False
        self._thread = threading.Thread(target=self._run, name=f"isight-pose-stream-{conn.label}", daemon=True)

    def start(self) -> PoseStream:
        gauge().start()  # the suite's own scheduling delay over the stream (timing verdicts on a loaded runner)
        self._thread.start()
        return self

    def stop(self) -> StreamResult:
        """Stop sending, wait (bounded by time_out) for the answers still due, and return the result."""
        self._stop.set()
        return self.wait()

    def wait(self, timeout_s: float | None = None) -> StreamResult:
        limit = timeout_s if timeout_s is not None else (self.duration_s or 0) + self.time_out_s + 2.0
        self._thread.join(limit)
        if self._thread.is_alive():  # never expected: every wait inside is bounded
            self._stop.set()
            self._thread.join(self.time_out_s + 2.0)
        if not self._thread.is_alive() and not self._stopped_gauge:
            self._stopped_gauge = True
            gauge().stop()
        return self.result

    @property
    def running(self) -> bool:
        return self._thread.is_alive()

    def _run(self) -> None:
        r, period = self.result, 1.0 / self.rate_hz
        count = None if self.duration_s is None else max(1, round(self.duration_s * self.rate_hz))
        codec, label = self.conn.codec, self.conn.label
        t0 = r.started_at = time.monotonic()
        try:
            while not self._stop.is_set() and (count is None or r.sent < count):
                due = t0 + r.sent * period
                if not self._read_until(due):
                    return
                pose = self.poses(r.sent)
                data = codec.encode(request(Action.POSE, codec.pose_blocks([pose])))
                now = time.monotonic()
                r.max_send_lag_ms = max(r.max_send_lag_ms, (now - due) * 1000)
                self._sent_at.append(now)
                self._frames.append(data)
                r.sent += 1
                if not self.conn.send(data, f"{label}: pose {r.sent}"):
                    if self.conn.closed_by_peer is None:
                        r.ended = "blocked"  # the send did not complete within time_out
                    else:
                        self._end(self.conn.closed_by_peer)
                    return
            while r.answered < r.sent and not r.ended:  # the answers still due, bounded by time_out
                if not self._read_until(time.monotonic() + 0.05):
                    return
        finally:
            r.elapsed_s = time.monotonic() - t0

    def _read_until(self, until: float) -> bool:
        """Read answers until ``until``; False when the stream must end."""
        r = self.result
        while True:
            now = time.monotonic()
            limit = min(self.conn.stream_bound or self.time_out_s, self.time_out_s)
            if r.answered < r.sent and now - self._sent_at[r.answered] > limit:
                late = self.conn.next_outcome(0.0)  # one last look: the suite may have been kept from running
                due = self._sent_at[r.answered] + limit
                if not isinstance(late, Answer) or self.conn.last_arrival > due:
                    r.ended = "overdue"
                    self._overdue(limit)
                    return False
                self._take(late)
                continue
            if now >= until:
                return True
            outcome = self.conn.next_outcome(max(until - now, 0.0002))
            if isinstance(outcome, Silence):
                continue
            if not isinstance(outcome, Answer):
                self._end(outcome)
                return False
            if not self._take(outcome):
                return False

    def _overdue(self, limit: float) -> None:
        """A pose unanswered for ``limit``: noted for the session's wait patterns (:mod:`.waits`) after a
        full time_out; after a short bound, kept as a cut (INCONCLUSIVE) if a fresh connection is answered."""
        conn = self.conn
        if limit >= self.time_out_s:
            if conn.on_ran_out is not None:
                conn.on_ran_out(STREAM)
        elif responsive(check_alive(conn.transcript, conn.target, conn.profile)):
            self.result.cut_s = limit

    def _take(self, outcome: Answer) -> bool:
        """Match an answer to the oldest pose unanswered (A1: in order); False for one beyond the poses sent.
        Its latency runs to the kernel's receive time (not to when the suite got round to reading it)."""
        r = self.result
        k = r.answered
        if k >= r.sent:
            r.extra += 1
            if r.bad is None:
                r.bad, r.bad_index = outcome, k
            return False
        r.latencies_ms.append((min(time.monotonic(), self.conn.last_arrival) - self._sent_at[k]) * 1000)
        if r.bad is None and not self.expect.matches(outcome):
            r.bad, r.bad_index, r.bad_sent = outcome, k, self._frames[k]
        r.answered += 1
        return True

    def _end(self, outcome: Outcome) -> None:
        r = self.result
        r.ended_by = outcome
        r.ended = "malformed" if isinstance(outcome, Malformed) else "reset" if getattr(outcome, "reset", False) else "closed"


def judge_stream(r: StreamResult, level: Level, what: str, max_lost: int = 0, backlog: bool = False,
                 clauses: tuple[str, ...] = ()) -> None:
    """Raise the verdict for a stream: a wrong answer, lost answers, or (``backlog``) latency that grew;
    ``what`` names the stream, ``clauses`` what its verdicts judge."""
    lead = "/".join(clauses)
    what = f"{lead}: {what}" if lead else what
    if r.bad is not None and r.extra == 0:
        check(r.bad, answered(Action.POSE, [0]), level, f"{what}: pose {r.bad_index + 1} is answered 0000",
              sent=r.bad_sent, judged=clauses)
    if r.extra:
        raise fail(level, f"A1/{what}: exactly one answer per pose", f"{r.sent} answers",
                   f"{r.extra} answer(s) more than poses sent", judged=tuple(dict.fromkeys(("A1", *clauses))))
    if r.ended == "malformed" and r.ended_by is not None:
        check(r.ended_by, answered(Action.POSE), level, f"{what}: every pose is answered with a well-formed frame",
              judged=clauses)
    if r.lost > max_lost and r.cut_s:
        raise Inconclusive(
            f"{what}: pose {r.answered + 1} was not answered within {r.cut_s * 1000:.0f} ms; streams of earlier "
            "cases left a pose unanswered for the whole time_out (and the box still answers a fresh connection), "
            "so this stream ended there, not judged", judged=clauses, signature=Signature(Sig.SILENCE, "POSE"))
    if r.lost > max_lost:
        why = {"overdue": f"pose {r.answered + 1} got no answer within time_out ({r.time_out_s * 1000:.0f} ms)",
               "closed": "the box closed the connection", "reset": "the box reset the connection",
               "blocked": "the box stopped reading (a send did not complete within time_out)"}.get(r.ended, "")
        raise fail(level, f"{what}: every pose is answered (none lost)", f"{r.sent} answers" + (
            f" (at most {max_lost} lost)" if max_lost else ""), f"{r.answered} answers, {r.lost} lost" + (f": {why}" if why else ""),
            judged=clauses)
    b = r.backlog() if backlog else None
    if b is not None and b[1] > b[2]:
        n = len(r.latencies_ms) // 4  # the last quarter's poses: was each one's wait overlapped by a stall that long?
        last = [(r.sent_at[k], r.sent_at[k] + r.latencies_ms[k] / 1000) for k in range(len(r.latencies_ms) - n,
                                                                                     len(r.latencies_ms))]
        if len(r.sent_at) >= len(r.latencies_ms) and starved_share(last, b[1] - b[2]) >= 0.5:
            raise Inconclusive(starved_text(b[1] - b[2], gauge().worst_ms(last[0][0], last[-1][1]),
                                            "the last quarter's p50 answer latency (T2 backlog)"), judged=clauses)
        raise fail(level, f"{what}: answer latency does not grow over the run (backlog)",
                   f"last-quarter p50 ≤ {b[2]:.1f} ms (first-quarter p50 {b[0]:.1f} ms + max(20 ms, itself))",
                   f"backlog: last-quarter p50 {b[1]:.1f} ms", judged=clauses, signature=Signature(Sig.BACKLOG))


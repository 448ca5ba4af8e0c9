"""T2 from a capture: the robot's stream rate and jitter, the box's backlog.

The robot side reuses certify-robot's judgement (:mod:`conformance.observed.stream_timing`:
:func:`stream_stats`, :func:`judge_rate`, :func:`judge_jitter`) on the time stamps of
the robot's pose frames, in blocks of :data:`BLOCK` poses so that the memory a stream
needs does not grow with its length (a block's figures are kept, its time stamps are
not). A gap in the capture ends a block: an interval across missing bytes is not a
measurement.

The box side reuses the active suite's backlog figure (:meth:`StreamResult.backlog
<conformance.suite.pose_stream.StreamResult.backlog>`: last-quarter p50 latency above
first-quarter p50 + max(20 ms, first-quarter p50)) on an evenly spaced sample of the stream's answer
latencies.
"""

from __future__ import annotations

from array import array
from collections.abc import Callable
from dataclasses import dataclass, field

from ..observed.stream_timing import jitter_starved, judge_jitter, judge_rate, rate_starved, stream_stats
from ..suite.pose_stream import StreamResult
from .findings import Series

__all__ = ["BLOCK", "Backlog", "PoseClock", "StreamJudgement", "backlog"]

#: poses judged together (about 22 minutes at 50 Hz)
BLOCK = 65536


@dataclass
class StreamJudgement:
    """T2 for one robot stream: the first failing rate and jitter texts, or the passing ones."""

    poses: int = 0
    blocks: int = 0
    rate_ok: bool = True
    rate_text: str = ""
    jitter_ok: bool = True
    jitter_text: str = ""
    described: list[str] = field(default_factory=list)  # each block's figures
    starved: str = ""  # a breach the monitoring side's own stalls could explain (INCONCLUSIVE, not FAIL)
    windows_hz: list[float] = field(default_factory=list)  # the first blocks' per-second rates

    @property
    def ok(self) -> bool:
        return self.rate_ok and self.jitter_ok


class PoseClock:
    """The send times of one connection's pose frames, judged block by block."""

    def __init__(self, rate_hz: float, rate_tolerance: float, jitter_tolerance: float,
                 intervals: Series | None = None, block: int = BLOCK, peer_local: bool = False) -> None:
        self.rate_hz = rate_hz
        self.peer_local = peer_local  # the robot runs on this host (its jitter may be the host's CPU contention)
        self.rate_tolerance = rate_tolerance
        self.jitter_tolerance = jitter_tolerance
        self.intervals = intervals  # where every measured interval also goes (the report's histogram)
        self.block = block
        self.times = array("d")  # callers may append to it directly, then call flush() at BLOCK
        self.judgement = StreamJudgement()
        self.poses = 0
        self._carried = False  # times[0] is the previous block's last pose

    def add(self, t: float) -> None:
        self.times.append(t)
        if len(self.times) >= self.block:
            self._judge(keep_last=True)

    def flush(self) -> None:
        """Judge the block so far; its last time stamp starts the next one."""
        self._judge(keep_last=True)

    def cut(self) -> None:
        """A gap: the interval across it is not measured."""
        self._judge(keep_last=False)

    def finish(self) -> StreamJudgement:
        self._judge(keep_last=False)
        self.judgement.poses = self.poses
        return self.judgement

    def _judge(self, keep_last: bool) -> None:
        times = self.times
        j = self.judgement
        self.poses += len(times) - (1 if self._carried else 0)
        stats = stream_stats(times, self.rate_hz)  # None below MIN_POSES
        if stats is not None:
            j.blocks += 1
            ok, text = self._unless_starved(judge_rate(stats, self.rate_tolerance),
                                            lambda: rate_starved(stats, times, self.rate_tolerance))
            if j.rate_ok:
                j.rate_ok, j.rate_text = ok, text
            ok, text = self._unless_starved(judge_jitter(stats, self.jitter_tolerance),
                                            lambda: jitter_starved(stats, times, self.jitter_tolerance, self.peer_local))
            if j.jitter_ok:
                j.jitter_ok, j.jitter_text = ok, text
            if len(j.described) < 8:
                j.described.append(stats.describe())
            if len(j.windows_hz) < 600:
                j.windows_hz += [round(w.rate_hz, 2) for w in stats.windows][: 600 - len(j.windows_hz)]
            if self.intervals is not None:
                self.intervals.extend(stats.intervals_ms, peaks=False)
        self._carried = keep_last and bool(times)
        self.times = array("d", [times[-1]]) if self._carried else array("d")

    def _unless_starved(self, judged: tuple[bool, str], starving: Callable[[], str | None]) -> tuple[bool, str]:
        """A breach the live monitor's own stalls could explain is not a FAIL (the gauge runs only while
        ``monitor`` watches live traffic: a capture's time stamps are the wire's)."""
        ok, text = judged
        reason = None if ok else starving()
        if reason is None:
            return judged
        self.judgement.starved = self.judgement.starved or f"{reason}. {text}"
        return True, text


@dataclass(frozen=True)
class Backlog:
    first_p50_ms: float
    last_p50_ms: float
    threshold_ms: float

    @property
    def grows(self) -> bool:
        return self.last_p50_ms > self.threshold_ms


def backlog(latencies: Series, rate_hz: float) -> Backlog | None:
    """The active suite's T2 backlog figure on the stream's latency sample (None below 8 answers), with a
    threshold of at least one stream period above the first quarter's p50: seen from the wire, a backlog is
    a box at least one pose behind, not a loaded machine's scheduling (issue 26's pairs, at 20 Hz)."""
    b = StreamResult(rate_hz=rate_hz, latencies_ms=latencies.sample).backlog()
    if b is None:
        return None
    first, last, threshold = b
    period_ms = 1000.0 / rate_hz if rate_hz > 0 else 0.0
    return Backlog(first, last, max(threshold, first + period_ms))

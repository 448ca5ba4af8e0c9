"""T2 from the robot's side: the pose stream's rate and send-interval jitter (pure functions).

Measured at the box from the arrival time of each pose frame (the chunk that completed
it), which is what a box sees; frames that arrive together (a burst, or the robot's TCP
stack coalescing them) have intervals near 0.

* **rate** — the mean rate over the stream, and the rate of every window of about one
  second (``max(10, rate)`` intervals), each within ``tolerance`` of the declared rate:
  a drifting clock fails on its later windows even when its mean is close;
* **jitter** — the 99th percentile of ``|interval − 1/rate|`` within ``tolerance`` of
  the period: a bursty sender (several frames at once, then a gap) fails here while
  its mean rate is right.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

from ..harness.starvation import gauge, host_starved_text, starved_text, starved_verdict
from ..model.percentiles import percentile

#: Below this many poses no rate is measured.
MIN_POSES = 3


@dataclass(frozen=True)
class Window:
    start_ms: float  # from the first pose
    intervals: int
    rate_hz: float


@dataclass(frozen=True)
class StreamStats:
    poses: int
    declared_hz: float
    duration_s: float
    intervals_ms: tuple[float, ...]
    mean_rate_hz: float
    windows: tuple[Window, ...]
    dev_p50_ms: float  # |interval - period|
    dev_p99_ms: float
    dev_max_ms: float
    together: int  # intervals under 0.5 ms: frames that arrived in one go

    @property
    def period_ms(self) -> float:
        return 1000.0 / self.declared_hz

    def describe(self) -> str:
        return (f"{self.poses} poses in {self.duration_s:.3f} s: mean {self.mean_rate_hz:.2f} Hz "
                f"(declared {self.declared_hz:g} Hz); |interval − {self.period_ms:.2f} ms| p50 {self.dev_p50_ms:.2f} ms, "
                f"p99 {self.dev_p99_ms:.2f} ms, max {self.dev_max_ms:.2f} ms; {self.together} interval(s) under 0.5 ms")
#: the host's CPU pressure is read around an interval this much wider on each side (its samples are 50 ms apart)
PSI_MARGIN_S = 0.05


def stream_stats(times_s: Sequence[float], declared_hz: float) -> StreamStats | None:
    """Statistics of one stream's pose arrival times (seconds, ascending); None below MIN_POSES."""
    if len(times_s) < MIN_POSES or not declared_hz > 0:
        return None
    times = sorted(times_s)
    intervals = [(b - a) * 1000.0 for a, b in zip(times, times[1:])]
    duration = times[-1] - times[0]
    mean = (len(intervals) / duration) if duration > 0 else math.inf
    period = 1000.0 / declared_hz
    size = max(10, round(declared_hz))
    windows = []
    elapsed = 0.0
    for start in range(0, len(intervals), size):
        chunk = intervals[start : start + size]
        span = sum(chunk)
        if len(chunk) >= size / 2 or start == 0:
            windows.append(Window(round(elapsed, 3), len(chunk), len(chunk) / (span / 1000.0) if span > 0 else math.inf))
        elapsed += span
    devs = sorted(abs(i - period) for i in intervals)
    return StreamStats(
        poses=len(times), declared_hz=declared_hz, duration_s=duration, intervals_ms=tuple(intervals),
        mean_rate_hz=mean, windows=tuple(windows), dev_p50_ms=percentile(devs, 50), dev_p99_ms=percentile(devs, 99),
        dev_max_ms=devs[-1], together=sum(1 for i in intervals if i < 0.5),
    )


def check_tolerances(rate_tolerance: float, jitter_tolerance: float) -> None:
    """ValueError (one line) unless the rate tolerance is in (0, 1) and the jitter tolerance in (0, 10]."""
    if not 0 < rate_tolerance < 1:
        raise ValueError(f"rate tolerance must be in (0, 100) %, not {rate_tolerance * 100:g} %")
    if not 0 < jitter_tolerance <= 10:
        raise ValueError(f"jitter tolerance must be in (0, 1000] %, not {jitter_tolerance * 100:g} %")


def _off(rate: float, declared: float) -> float:
    return (rate - declared) / declared if math.isfinite(rate) else math.inf


def judge_rate(stats: StreamStats, tolerance: float) -> tuple[bool, str]:
    """(ok, one line): the mean rate and every window within ``tolerance`` of the declared rate."""
    declared = stats.declared_hz
    mean_off = _off(stats.mean_rate_hz, declared)
    bad = [w for w in stats.windows if abs(_off(w.rate_hz, declared)) > tolerance]
    limits = f"{declared * (1 - tolerance):.2f}–{declared * (1 + tolerance):.2f} Hz (±{tolerance * 100:g} %)"
    if abs(mean_off) > tolerance:
        return False, (f"mean stream rate {stats.mean_rate_hz:.2f} Hz is {mean_off * 100:+.1f} % off the declared "
                       f"{declared:g} Hz; allowed {limits}")
    if bad:
        worst = max(bad, key=lambda w: abs(_off(w.rate_hz, declared)))
        first, last = stats.windows[0], stats.windows[-1]
        return False, (f"{len(bad)} of {len(stats.windows)} one-second windows outside {limits}: at +{worst.start_ms:.0f} ms "
                       f"{worst.rate_hz:.2f} Hz ({_off(worst.rate_hz, declared) * 100:+.1f} %); first window "
                       f"{first.rate_hz:.2f} Hz, last {last.rate_hz:.2f} Hz (mean {stats.mean_rate_hz:.2f} Hz)")
    return True, (f"mean {stats.mean_rate_hz:.2f} Hz ({mean_off * 100:+.1f} %) and all {len(stats.windows)} "
                  f"window(s) within {limits}")


def judge_jitter(stats: StreamStats, tolerance: float) -> tuple[bool, str]:
    """(ok, one line): p99 of |interval − period| within ``tolerance`` × period."""
    limit = tolerance * stats.period_ms
    text = (f"p99 |interval − {stats.period_ms:.2f} ms| = {stats.dev_p99_ms:.2f} ms "
            f"({stats.dev_p99_ms / stats.period_ms * 100:.0f} % of the period); allowed {limit:.2f} ms "
            f"({tolerance * 100:g} %)")
    if stats.dev_p99_ms > limit:
        extra = f"; {stats.together} of {len(stats.intervals_ms)} poses arrived together with the one before (bursts)" \
            if stats.together else ""
        return False, text + extra
    return True, text


def _span_excess_ms(intervals: int, span_ms: float, declared: float, tolerance: float) -> float:
    """How far a span of ``intervals`` intervals is outside the spans the rate tolerance allows (ms; 0 inside)."""
    if intervals <= 0:
        return 0.0
    longest = intervals / (declared * (1 - tolerance)) * 1000.0
    shortest = intervals / (declared * (1 + tolerance)) * 1000.0
    return max(0.0, span_ms - longest, shortest - span_ms)


def rate_excess_ms(stats: StreamStats, tolerance: float) -> float:
    """How much time the stream (or its worst one-second window) is off the rate tolerance: the delay a stall
    of the measuring side would have to explain (ms; 0 when within)."""
    worst = _span_excess_ms(len(stats.intervals_ms), stats.duration_s * 1000.0, stats.declared_hz, tolerance)
    size = max(10, round(stats.declared_hz))
    for start in range(0, len(stats.intervals_ms), size):
        chunk = stats.intervals_ms[start : start + size]
        if len(chunk) >= size / 2 or start == 0:
            worst = max(worst, _span_excess_ms(len(chunk), sum(chunk), stats.declared_hz, tolerance))
    return worst


def jitter_excess_ms(stats: StreamStats, tolerance: float) -> float:
    """How far the p99 interval deviation is above the jitter tolerance (ms; 0 when within)."""
    return max(0.0, stats.dev_p99_ms - tolerance * stats.period_ms)


def rate_starved(stats: StreamStats, times: Sequence[float], tolerance: float) -> str | None:
    """The INCONCLUSIVE reason when a stall of the judging side (its wall-clock time stamps) could explain a
    rate breach: one stall at least as long as the time the stream is off by (None: the breach stands)."""
    excess = rate_excess_ms(stats, tolerance)
    return starved_verdict(excess, min(times), max(times), "the stream's rate", wall=True) if excess else None


def jitter_starved(stats: StreamStats, times: Sequence[float], tolerance: float,
                   peer_local: bool = False) -> str | None:
    """The INCONCLUSIVE reason when the judging side's stalls could explain a jitter breach: every interval
    off by more than the tolerance overlaps a stall at least that large, but for as many as the p99 allows.
    ``peer_local``: the sender runs on this host, so the host's CPU contention (PSI) around an interval can
    explain it too (the sender's own stall, which the suite's timer cannot see)."""
    excess = jitter_excess_ms(stats, tolerance)
    if not excess:
        return None
    ordered, limit = sorted(times), tolerance * stats.period_ms
    off = [(ordered[i], ordered[i + 1], dev - limit) for i, dev in
           ((i, abs(v - stats.period_ms)) for i, v in enumerate(stats.intervals_ms)) if dev > limit]
    allowed = len(stats.intervals_ms) // 100
    what = f"the send-interval jitter ({len(off)} interval(s) off)"
    unexplained = [w for w in off if gauge().worst_ms(w[0], w[1], wall=True) < w[2]]
    if len(unexplained) <= allowed:
        return starved_text(excess, max(gauge().worst_ms(a, b, wall=True) for a, b, _ in off), what)
    if not peer_local:
        return None
    host = [(w, gauge().host_stall_ms(w[0] - PSI_MARGIN_S, w[1] + PSI_MARGIN_S, wall=True)) for w in unexplained]
    if sum(1 for w, stall in host if stall < w[2]) > allowed:
        return None
    return host_starved_text(excess, max(stall for _, stall in host), what)

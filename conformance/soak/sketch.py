"""Streaming latency statistics with bounded memory: a log-bucketed histogram.

A soak sees millions of answers; it keeps none of them. Each window's latencies go into a
:class:`LatencySketch`: buckets whose bounds grow by :data:`GAMMA` (2 %), so a quantile read
back is within 1 % of the exact one (the bucket's geometric middle), whatever the number of
samples. The count, sum, minimum and maximum are exact. Memory is bounded by the range of
values, not their number: 1 µs to 10 min is under 1,000 buckets, and a window of a healthy box
uses a few dozen.
"""

from __future__ import annotations

import math
from collections.abc import Iterable

#: the ratio between a bucket's upper and lower bound
GAMMA = 1.02
#: values at or below this (ms) share bucket 0 (1 µs: below the clock's meaning on loopback)
FLOOR_MS = 0.001
_LOG_GAMMA = math.log(GAMMA)


class LatencySketch:
    """Count, sum, min, max and bucketed quantiles of latencies in ms; ``add`` is O(1)."""

    __slots__ = ("buckets", "count", "max", "min", "total")

    def __init__(self, values: Iterable[float] = ()) -> None:
        self.buckets: dict[int, int] = {}
        self.count = 0
        self.total = 0.0
        self.min = math.inf
        self.max = -math.inf
        for value in values:
            self.add(value)

    @staticmethod
    def index(value_ms: float) -> int:
        if value_ms <= FLOOR_MS:
            return 0
        return max(1, math.ceil(math.log(value_ms / FLOOR_MS) / _LOG_GAMMA))

    @staticmethod
    def middle(index: int) -> float:
        """The value a bucket stands for: the geometric middle of its bounds."""
        if index <= 0:
            return FLOOR_MS
        return FLOOR_MS * GAMMA ** (index - 0.5)

    def add(self, value_ms: float) -> None:
        if not math.isfinite(value_ms):
            return
        value_ms = max(0.0, value_ms)
        i = self.index(value_ms)
        self.buckets[i] = self.buckets.get(i, 0) + 1
        self.count += 1
        self.total += value_ms
        self.min = min(self.min, value_ms)
        self.max = max(self.max, value_ms)

    def merge(self, other: LatencySketch) -> None:
        for i, n in other.buckets.items():
            self.buckets[i] = self.buckets.get(i, 0) + n
        self.count += other.count
        self.total += other.total
        self.min = min(self.min, other.min)
        self.max = max(self.max, other.max)

    def quantile(self, q: float) -> float:
        """The q-th percentile (q in [0, 100]), within 1 % of the exact; NaN when empty. q=100 is the max."""
        if not self.count:
            return math.nan
        if q >= 100:
            return self.max
        if q <= 0:
            return self.min
        rank = q / 100 * (self.count - 1)  # the 0-based rank of the wanted sample
        seen = 0
        for i in sorted(self.buckets):
            seen += self.buckets[i]
            if seen > rank:
                return min(self.max, max(self.min, self.middle(i)))
        return self.max

    @property
    def mean(self) -> float:
        return self.total / self.count if self.count else math.nan


__all__ = ["FLOOR_MS", "GAMMA", "LatencySketch"]

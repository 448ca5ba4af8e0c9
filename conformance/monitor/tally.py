"""The monitor's running totals for the metrics and the live page (sans-I/O).

Each connection's counts live in the engine's judge of it
(:class:`~conformance.analyze.exchanges.ConnJudge`: requests and answers per action,
poses, answers per error code); when a connection is gone :meth:`Tally.add` folds them
into totals, so the totals are those of the connections gone plus those still open and
memory does not grow with the number of connections. :class:`Buckets` is a latency
histogram with Prometheus's cumulative buckets (seconds), fed as answers are paired.
"""

from __future__ import annotations

from bisect import bisect_left
from collections.abc import Iterable
from typing import Any

from ..analyze.findings import Series

__all__ = ["BOUNDS_S", "Buckets", "ObservedSeries", "Tally"]

#: histogram bucket upper bounds (seconds): 1 ms .. 10 s, around the default time_out of 5 s
BOUNDS_S = (0.001, 0.0025, 0.005, 0.01, 0.025, 0.05, 0.1, 0.25, 0.5, 1.0, 2.5, 5.0, 10.0)


class Buckets:
    """A histogram of latencies given in ms, kept in seconds: counts per bucket, their sum."""

    def __init__(self, bounds: tuple[float, ...] = BOUNDS_S) -> None:
        self.bounds = bounds
        self.counts = [0] * (len(bounds) + 1)  # the last one: above every bound (+Inf only)
        self.sum_s = 0.0
        self.n = 0

    def observe(self, ms: float) -> None:
        s = ms / 1000.0
        self.counts[bisect_left(self.bounds, s)] += 1
        self.sum_s += s
        self.n += 1

    def cumulative(self) -> list[tuple[str, float]]:
        """[(upper bound as Prometheus writes it, count of values <= it)], ending with +Inf."""
        out, total = [], 0
        for bound, count in zip(self.bounds, self.counts):
            total += count
            out.append((repr(float(bound)), float(total)))
        out.append(("+Inf", float(self.n)))
        return out


class ObservedSeries(Series):
    """The engine's command-latency series that also feeds a :class:`Buckets`."""

    __slots__ = ("buckets",)

    def __init__(self, buckets: Buckets, cap: int = 4096) -> None:
        super().__init__(cap)
        self.buckets = buckets

    def add(self, v: float) -> None:
        super().add(v)
        self.buckets.observe(v)


def _merge(into: dict[int, int], more: dict[int, int]) -> None:
    for key, n in more.items():
        into[key] = into.get(key, 0) + n


class Tally:
    """Requests and answers per action, answers per error code, poses: of the connections gone."""

    def __init__(self) -> None:
        self.requests: dict[int, int] = {}
        self.answers: dict[int, int] = {}
        self.codes: dict[int, int] = {}
        self.poses = 0
        self.pose_answers = 0
        self.robot_errors = 0
        self.box_errors = 0

    def add(self, judge: Any) -> None:
        if judge is None:
            return
        _merge(self.requests, judge.robot_counts)
        _merge(self.answers, judge.box_counts)
        _merge(self.codes, judge.answer_codes)
        self.poses += judge.poses
        self.pose_answers += judge.box_poses
        self.robot_errors += judge.robot_errors
        self.box_errors += judge.box_errors

    def with_open(self, judges: Iterable[Any]) -> Tally:
        """These totals plus the connections still open (a new Tally)."""
        out = Tally()
        out.add(self)  # a Tally has the judge's fields under the same names, see the properties below
        for j in judges:
            out.add(j)
        return out

    # a Tally reads like a judge for :meth:`add`
    @property
    def robot_counts(self) -> dict[int, int]:
        return self.requests

    @property
    def box_counts(self) -> dict[int, int]:
        return self.answers

    @property
    def answer_codes(self) -> dict[int, int]:
        return self.codes

    @property
    def box_poses(self) -> int:
        return self.pose_answers

"""Trend statistics of a series of windows, pure and dependency-free.

* :func:`theil_sen`: the Theil–Sen slope (the median of the slopes between every pair of
  points) with Sen's (1968) confidence interval, equation 2.6, ties corrected, the same
  estimator and interval as ``scipy.stats.theilslopes`` (scipy is not a dependency of this
  project: this module is short and tested against textbook values and simulations instead).
  It shrugs off outliers: up to 29 % of the windows may be wild without moving it.
* :func:`mann_kendall`: the Mann–Kendall trend test (Kendall's S between time and value, its
  variance with ties corrected, the continuity-corrected normal score and its p-values).

Neither keeps anything beyond the points handed in; :func:`thin` bounds their number (an
eight-hour soak of one-minute windows is 480 points; judged as 240 medians of two, 29,000 pairs, at
every checkpoint).
"""

from __future__ import annotations

import math
from collections import Counter
from collections.abc import Sequence
from dataclasses import dataclass
from statistics import NormalDist, median

#: the most points a trend is computed on (more are merged, by median, into this many)
MAX_POINTS = 240
_NORMAL = NormalDist()


@dataclass(frozen=True)
class Slope:
    """A Theil–Sen fit: ``value ≈ intercept + slope × x``, the slope within [low, high] at ``confidence``."""

    slope: float
    intercept: float
    low: float
    high: float
    confidence: float
    points: int

    def to_dict(self) -> dict[str, float | int]:
        return {"slope": self.slope, "intercept": self.intercept, "low": self.low, "high": self.high,
                "confidence": self.confidence, "points": self.points}


@dataclass(frozen=True)
class MannKendall:
    """Kendall's S, its variance, the normal score z and p-values (two-sided; one-sided for a rise)."""

    s: int
    variance: float
    z: float
    p: float
    p_increasing: float
    tau: float
    points: int

    def to_dict(self) -> dict[str, float | int]:
        return {"s": self.s, "variance": self.variance, "z": self.z, "p": self.p,
                "p_increasing": self.p_increasing, "tau": self.tau, "points": self.points}


def _tie_term(values: Sequence[float]) -> float:
    return sum(t * (t - 1) * (2 * t + 5) for t in Counter(values).values() if t > 1)


def _s_variance(n: int, xs: Sequence[float], ys: Sequence[float]) -> float:
    return (n * (n - 1) * (2 * n + 5) - _tie_term(xs) - _tie_term(ys)) / 18.0


def theil_sen(xs: Sequence[float], ys: Sequence[float], confidence: float = 0.95) -> Slope:
    """The Theil–Sen slope of ``ys`` over ``xs`` with Sen's confidence interval; ValueError under 2 distinct xs."""
    if len(xs) != len(ys):
        raise ValueError("theil_sen: xs and ys differ in length")
    n = len(xs)
    slopes = sorted((ys[j] - ys[i]) / (xs[j] - xs[i])
                    for i in range(n) for j in range(i + 1, n) if xs[j] != xs[i])
    if not slopes:
        raise ValueError("theil_sen: needs at least two points with different x")
    slope = median(slopes)
    intercept = median(ys) - slope * median(xs)
    z = _NORMAL.inv_cdf(0.5 + confidence / 2)
    sigma = math.sqrt(max(0.0, _s_variance(n, xs, ys)))
    count = len(slopes)
    lo_i = min(max(int(round((count - z * sigma) / 2.0)), 0), count - 1)
    hi_i = min(max(int(round((count + z * sigma) / 2.0)) - 1, 0), count - 1)
    low, high = sorted((slopes[lo_i], slopes[hi_i]))
    return Slope(slope, intercept, low, high, confidence, n)


def mann_kendall(ys: Sequence[float]) -> MannKendall:
    """The Mann–Kendall test of a trend in ``ys`` (in time order); ValueError under 3 points."""
    n = len(ys)
    if n < 3:
        raise ValueError("mann_kendall: needs at least three points")
    s = 0
    for i in range(n - 1):
        yi = ys[i]
        for j in range(i + 1, n):
            d = ys[j] - yi
            s += (d > 0) - (d < 0)
    variance = (n * (n - 1) * (2 * n + 5) - _tie_term(ys)) / 18.0
    if variance <= 0:
        z = 0.0
    elif s > 0:
        z = (s - 1) / math.sqrt(variance)
    elif s < 0:
        z = (s + 1) / math.sqrt(variance)
    else:
        z = 0.0
    p = 2.0 * (1.0 - _NORMAL.cdf(abs(z)))
    return MannKendall(s, variance, z, min(1.0, p), 1.0 - _NORMAL.cdf(z), s / (n * (n - 1) / 2), n)


def thin(xs: Sequence[float], ys: Sequence[float], most: int = MAX_POINTS) -> tuple[list[float], list[float]]:
    """At most ``most`` points: consecutive groups merged into their medians (x and y each)."""
    n = len(xs)
    if n <= most:
        return list(xs), list(ys)
    size = math.ceil(n / most)
    out_x, out_y = [], []
    for start in range(0, n, size):
        out_x.append(median(xs[start:start + size]))
        out_y.append(median(ys[start:start + size]))
    return out_x, out_y


def residual_spread(xs: Sequence[float], ys: Sequence[float], fit: Slope) -> float:
    """The noise around a fit: 1.4826 × the median absolute residual (σ for Gaussian noise)."""
    residuals = [y - (fit.intercept + fit.slope * x) for x, y in zip(xs, ys)]
    return 1.4826 * median(abs(r) for r in residuals) if residuals else 0.0


__all__ = ["MAX_POINTS", "MannKendall", "Slope", "mann_kendall", "residual_spread", "theil_sen", "thin"]

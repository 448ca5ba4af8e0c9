"""The soak's verdicts: trends over the windows, and what stopped.

Judged as a trend, not a snapshot:

* **T2**, answer latency: the Theil–Sen slope of each window's pose-answer p50 and p99 over time,
  with its 95 % interval, and the Mann–Kendall test. Latency grows *beyond noise* when the test
  finds a rise (one-sided p < :data:`ALPHA`), the interval lies above zero, and the growth over
  the soak (slope × span) exceeds both :data:`LATENCY_FLOOR_MS` and three times the scatter of the
  windows around the fit. Then T2 FAILs, with the slope and the windows that show it.
* Growth must be *sustained*: the slope over the later half of the windows is at least a third of the
  whole soak's, so a box warming up (a climb that levels off) is not a trend.
* **Resources** of a local box (RSS, file descriptors, threads, CPU, connections it holds), by the
  same rule with each resource's own floor (:data:`RESOURCE_FLOORS`): a growing one is a *finding*,
  "RSS +3.1 MB per 1,000 sessions (95 % CI 2.8–3.4)", reported under R5.
* **S5/R5**: a box that stops serving (every session fails to the end) FAILs with the number of
  sessions it served first; S5 when connections are refused or not accepted, R5 when it dropped live
  connections or did not serve a robot that came back after vanishing.
* **T1, S4, S1**: answers beyond time_out, commands starved while the stream was served, wrong answers.

A flat box passes, and every message says how long and how many sessions the verdict covers.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

from ..model.verdicts import Verdict
from ..report.summary import format_duration
from .trend import Slope, mann_kendall, residual_spread, theil_sen, thin
from .windows import FAILURE_CLAUSE, WindowRow

#: the Mann–Kendall test's level for "it rises"
ALPHA = 0.01
#: fewer windows than this: no trend is judged (INCONCLUSIVE)
MIN_WINDOWS = 6
#: latency growth over the soak below this is not a backlog (ms)
LATENCY_FLOOR_MS = 2.0
#: resource: (unit, absolute floor of growth over the soak, floor relative to its first level)
RESOURCE_FLOORS: dict[str, tuple[str, float, float]] = {
    "rss_mb": ("MB", 1.0, 0.02),
    "fds": ("fds", 4.0, 0.0),
    "threads": ("threads", 2.0, 0.0),
    "cpu_percent": ("% CPU", 10.0, 0.0),
    "connections": ("connections", 4.0, 0.0),
}
RESOURCE_NAMES = {"rss_mb": "RSS", "fds": "open file descriptors", "threads": "threads",
                  "cpu_percent": "CPU", "connections": "connections held (the soak's own half-open ones left out)"}


@dataclass
class Trend:
    """One series judged: its fits over hours and over thousands of sessions, the test, the verdict."""

    series: str
    unit: str
    per_hour: Slope | None
    per_k_sessions: Slope | None
    test: dict[str, Any] | None
    growth: float  # slope × span (hours), in the series' unit
    noise: float  # 3 × the scatter around the fit
    floor: float
    grows: bool
    first: float
    last: float
    windows: list[int] = field(default_factory=list)  # the windows above the first third's level
    later_per_hour: float = 0.0  # the slope over the later half of the windows

    def to_dict(self) -> dict[str, Any]:
        return {"series": self.series, "unit": self.unit, "grows": self.grows, "growth": self.growth,
                "noise": self.noise, "floor": self.floor, "first": self.first, "last": self.last,
                "per_hour": self.per_hour.to_dict() if self.per_hour else None,
                "per_1000_sessions": self.per_k_sessions.to_dict() if self.per_k_sessions else None,
                "mann_kendall": self.test, "windows": self.windows, "later_half_per_hour": self.later_per_hour}

    def slope_text(self, name: str, brief: bool = False) -> str:
        fit = self.per_k_sessions or self.per_hour
        if fit is None:
            return f"{name}: too few windows"
        per = "per 1,000 sessions" if self.per_k_sessions else "per hour"
        text = f"{name} {number(fit.slope, True)} {self.unit} {per} (95 % CI {number(fit.low)}–{number(fit.high)})"
        if brief:
            return text
        if self.per_hour is not None and self.per_k_sessions is not None:
            text += f", {number(self.per_hour.slope, True)} {self.unit} per hour"
        if self.test is not None:
            text += (f"; from {number(self.first)} to {number(self.last)} {self.unit} "
                     f"(Mann–Kendall p = {self.test['p_increasing']:.2g})")
        return text


@dataclass
class SoakVerdict:
    clause: str
    title: str
    verdict: Verdict
    message: str
    windows: list[int] = field(default_factory=list)
    details: dict[str, Any] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        return {"clause": self.clause, "title": self.title, "verdict": self.verdict.value, "message": self.message,
                "windows": self.windows, "details": self.details}


def number(value: float, sign: bool = False) -> str:
    """``3.1``, ``0.0123``, ``529``, ``13,400``: three significant figures, no exponent."""
    lead = "+" if sign and value > 0 else ""
    size = abs(value)
    if size >= 1000:
        return f"{lead}{value:,.0f}"
    if size >= 100 or value == 0:
        return f"{lead}{value:.0f}"
    if size >= 1:
        return f"{lead}{value:.3g}"
    return f"{lead}{value:.2g}"


def _median(values: Sequence[float]) -> float:
    ordered = sorted(values)
    return ordered[len(ordered) // 2] if ordered else 0.0


def judge_series(name: str, unit: str, rows: Sequence[WindowRow], value: Callable[[WindowRow], float | None],
                 floor_abs: float, floor_rel: float = 0.0, skip: int = 0) -> Trend | None:
    """The trend of one series over ``rows`` (after ``skip`` warm-up windows); None with too few points."""
    points = [(r, v) for r in rows[skip:] if (v := value(r)) is not None]
    if len(points) < MIN_WINDOWS:
        return None
    hours = [((r.start_s + r.end_s) / 2) / 3600 for r, _ in points]
    sessions = [r.sessions_total / 1000 for r, _ in points]
    ys = [float(v) for _, v in points]
    hx, hy = thin(hours, ys)
    per_hour = theil_sen(hx, hy)
    sx, sy = thin(sessions, ys)
    per_k = theil_sen(sx, sy) if len(set(sx)) > 1 else None
    test = mann_kendall(hy)
    span = hours[-1] - hours[0]
    growth = per_hour.slope * span
    noise = 3 * residual_spread(hx, hy, per_hour)
    third = max(1, len(ys) // 3)
    first, last = _median(ys[:third]), _median(ys[-third:])
    floor = max(floor_abs, floor_rel * abs(first))
    half = len(hx) // 2
    later = theil_sen(hx[half:], hy[half:]).slope if len(set(hx[half:])) > 1 else per_hour.slope
    sustained = later >= per_hour.slope / 3  # a warm-up climbs, then levels off: its later half is flat
    grows = test.p_increasing < ALPHA and per_hour.low > 0 and growth > max(floor, noise) and sustained
    above = [r.index for r, v in points if v > first + floor] if grows else []
    return Trend(name, unit, per_hour, per_k, test.to_dict(), growth, noise, floor, grows, first, last, above, later)


def _coverage(rows: Sequence[WindowRow]) -> str:
    if not rows:
        return "no window closed"
    span = rows[-1].end_s - rows[0].start_s
    return f"{format_duration(span)}, {rows[-1].sessions_total:,} sessions, {len(rows)} windows"


def _clause_windows(rows: Sequence[WindowRow], clause: str) -> tuple[int, list[int], list[str]]:
    count = 0
    windows: list[int] = []
    reasons: list[str] = []
    for row in rows:
        hits = sum(n for kind, n in row.failures.items() if FAILURE_CLAUSE.get(kind) == clause)
        if clause == "T1":
            hits += row.answers_late
        if hits:
            count += hits
            windows.append(row.index)
            for kind, texts in row.reasons.items():
                if FAILURE_CLAUSE.get(kind) == clause and len(reasons) < 3:
                    reasons.extend(t for t in texts if t not in reasons)
    return count, windows, reasons[:3]


__all__ = ["ALPHA", "LATENCY_FLOOR_MS", "MIN_WINDOWS", "RESOURCE_FLOORS", "RESOURCE_NAMES", "SoakVerdict", "Trend",
           "judge_series"]

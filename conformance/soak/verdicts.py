"""From the windows (and what the player saw stop) to one verdict per clause the soak judges."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

from ..model.verdicts import Verdict
from ..report.summary import format_duration
from .judge import (
    LATENCY_FLOOR_MS,
    MIN_WINDOWS,
    RESOURCE_FLOORS,
    RESOURCE_NAMES,
    SoakVerdict,
    Trend,
    _clause_windows,
    _coverage,
    judge_series,
)
from .windows import WindowRow

TITLES = {
    "S1": "Canonical sessions keep completing with 0000",
    "S4": "Command and stream connections served together, session after session",
    "S5": "Connections freed: the box keeps accepting session after session",
    "R5": "Resources bounded over the soak (and robots that vanish are served again)",
    "T1": "Every answer within time_out, all along",
    "T2": "Answer latency does not grow over the soak",
}


SHORT_NAMES = {"rss_mb": "RSS", "fds": "fds", "threads": "threads", "cpu_percent": "CPU", "connections": "connections"}


@dataclass
class Stopped:
    """The box stopped serving: every session from the ``after_sessions``-th on failed, to the end."""

    after_sessions: int
    at_s: float
    kind: str  # a failure kind of windows.FAILURE_CLAUSE, or "died" (the box's process ended)
    reason: str
    #: half-open connections of vanished robots the soak held open when the box stopped
    half_open: int = 0

    @property
    def clause(self) -> str:
        """R5 when the rebooted robot was refused (a vanished robot's connections held the box), else S5."""
        return "R5" if self.kind == "after-vanish" else "S5"

    def to_dict(self) -> dict[str, Any]:
        return {"after_sessions": self.after_sessions, "at_s": round(self.at_s, 3), "kind": self.kind,
                "reason": self.reason, "half_open": self.half_open, "clause": self.clause}


@dataclass
class Judged:
    verdicts: list[SoakVerdict]
    latency: list[Trend]
    resources: list[Trend]
    findings: list[str]

    @property
    def failed(self) -> bool:
        return any(v.verdict is Verdict.FAIL for v in self.verdicts)

    def to_dict(self) -> dict[str, Any]:
        return {"verdicts": [v.to_dict() for v in self.verdicts], "latency_trends": [t.to_dict() for t in self.latency],
                "resource_trends": [t.to_dict() for t in self.resources], "findings": self.findings}


def warmup(rows: Sequence[WindowRow]) -> int:
    """Windows left out of the resource trends: the first tenth (at least one), a box warming up."""
    return max(1, len(rows) // 10) if len(rows) > MIN_WINDOWS else 0


def _latency(q: str) -> Callable[[WindowRow], float | None]:
    def value(row: WindowRow) -> float | None:
        v = row.latency.get(q)
        return None if v is None else float(v)

    return value


def _resource(key: str) -> Callable[[WindowRow], float | None]:
    def value(row: WindowRow) -> float | None:
        return row.resources.get(key)

    return value


def latency_trends(rows: Sequence[WindowRow]) -> list[Trend]:
    out = []
    for q in ("p50", "p99"):
        trend = judge_series(f"latency {q}", "ms", rows, _latency(q), LATENCY_FLOOR_MS, 0.5)
        if trend is not None:
            out.append(trend)
    return out


def resource_trends(rows: Sequence[WindowRow]) -> list[Trend]:
    out = []
    skip = warmup(rows)
    for key, (unit, floor_abs, floor_rel) in RESOURCE_FLOORS.items():
        if not any(r.resources.get(key) is not None for r in rows):
            continue
        trend = judge_series(key, unit, rows, _resource(key), floor_abs, floor_rel, skip)
        if trend is not None:
            out.append(trend)
    return out


def _t2(rows: Sequence[WindowRow], trends: list[Trend]) -> SoakVerdict:
    cover = _coverage(rows)
    if not trends:
        return SoakVerdict("T2", TITLES["T2"], Verdict.INCONCLUSIVE,
                           f"too few windows with answers to judge a trend "
                           f"({sum(1 for r in rows if r.latency.get('n'))} of {len(rows)}; {MIN_WINDOWS} needed)")
    # a backlog moves the median: the p50 judges T2; a p99 that grows alone is the tail (often the host), a finding
    growing = [t for t in trends if t.grows and t.series == "latency p50"]
    details = {"trends": [t.to_dict() for t in trends]}
    if growing:
        worst = growing[0]
        return SoakVerdict("T2", TITLES["T2"], Verdict.FAIL,
                           f"answer latency grows beyond noise: {worst.slope_text(worst.series)}; "
                           f"growth {worst.growth:.3g} ms over the soak against noise {worst.noise:.3g} ms "
                           f"({cover}); windows {_ranges(worst.windows)}", worst.windows, details)
    tail = [t for t in trends if t.grows]
    if tail:
        return SoakVerdict("T2", TITLES["T2"], Verdict.PASS,
                           f"the median latency is flat over {cover}, the tail grows (a finding): "
                           + "; ".join(t.slope_text(t.series) for t in trends), tail[0].windows, details)
    return SoakVerdict("T2", TITLES["T2"], Verdict.PASS,
                       f"latency flat over {cover}: " + "; ".join(t.slope_text(t.series) for t in trends), [], details)


def _ranges(indexes: Sequence[int]) -> str:
    """``[1, 2, 3, 7]`` → ``1–3, 7``."""
    parts: list[str] = []
    for i in indexes:
        if parts and parts[-1].split("–")[-1] == str(i - 1):
            parts[-1] = f"{parts[-1].split('–')[0]}–{i}"
        else:
            parts.append(str(i))
    return ", ".join(parts) if parts else "none"


def _failure_clause(clause: str, rows: Sequence[WindowRow], stopped: Stopped | None, extra: str = "") -> SoakVerdict:
    count, windows, reasons = _clause_windows(rows, clause)
    cover = _coverage(rows)
    if stopped is not None and stopped.clause == clause:
        held = (f", with {stopped.half_open} connections of vanished robots still open"
                if stopped.half_open else "")
        return SoakVerdict(clause, TITLES[clause], Verdict.FAIL,
                           f"the box stopped serving after {stopped.after_sessions:,} sessions "
                           f"({format_duration(stopped.at_s)} into the soak{held}): {stopped.reason}", windows,
                           {"stopped": stopped.to_dict(), "failures": count})
    if count:
        return SoakVerdict(clause, TITLES[clause], Verdict.FAIL,
                           f"{count} failure(s) in windows {_ranges(windows)} ({cover}): " + " | ".join(reasons),
                           windows, {"failures": count})
    return SoakVerdict(clause, TITLES[clause], Verdict.PASS, f"none in {cover}{extra}", [], {})


def _nothing_judged(rows: Sequence[WindowRow]) -> Judged:
    not_ready = sum(r.sessions_not_ready for r in rows)
    why = (f"no session could be judged: {not_ready} ended not ready (CycleOn 0001 or ProgIdx 409, S2/E2)"
           if not_ready else "no session could be judged")
    return Judged([SoakVerdict(c, TITLES[c], Verdict.INCONCLUSIVE, why) for c in ("S1", "S4", "S5", "R5", "T1", "T2")],
                  [], [], [])


def judge_soak(rows: Sequence[WindowRow], stopped: Stopped | None, half_open: dict[str, Any] | None = None,
               held: Sequence[Stopped] = ()) -> Judged:
    """Every verdict of the soak, from its closed windows, what stopped, and the stops that ended once the soak
    reset the abandoned connections (``held``: they held the box, R5)."""
    if stopped is None and (not rows or not rows[-1].sessions_total):
        return _nothing_judged(rows)
    lat = latency_trends(rows)
    res = resource_trends(rows)
    grown = [t.slope_text(RESOURCE_NAMES.get(t.series, t.series)) for t in res if t.grows]
    median_grows = any(t.grows for t in lat if t.series == "latency p50")
    tail = [f"tail {t.slope_text(t.series)} (the median is flat)" for t in lat
            if t.grows and t.series != "latency p50" and not median_grows]
    verdicts = [_failure_clause("S1", rows, stopped), _failure_clause("S4", rows, stopped),
                _failure_clause("S5", rows, stopped), _failure_clause("T1", rows, stopped), _t2(rows, lat)]
    r5 = _failure_clause("R5", rows, stopped)
    if held:
        first = held[0]
        also = f"; also {r5.message}" if r5.verdict is Verdict.FAIL else ""
        r5 = SoakVerdict("R5", TITLES["R5"], Verdict.FAIL,
                         f"the box stopped serving after {first.after_sessions:,} sessions "
                         f"({format_duration(first.at_s)} into the soak) with {first.half_open} connections of "
                         "vanished robots open, and served again once the soak reset them: abandoned connections "
                         f"are not freed ({len(held)} time(s); {_coverage(rows)}){also}", r5.windows,
                         {**r5.details, "held": [h.to_dict() for h in held]})
    r5.details["resource_trends"] = [t.to_dict() for t in res]
    if half_open:
        r5.details["half_open"] = half_open
    if r5.verdict is Verdict.PASS and grown:
        growing = [t for t in res if t.grows]
        r5 = SoakVerdict("R5", TITLES["R5"], Verdict.INFORMATIONAL,
                         "resources grow: " + "; ".join(grown) + f" ({_coverage(rows)})",
                         sorted({i for t in growing for i in t.windows}), r5.details)
    elif r5.verdict is Verdict.PASS and res:
        r5.message += "; resources flat: " + "; ".join(t.slope_text(SHORT_NAMES.get(t.series, t.series), brief=True)
                                                      for t in res)
    verdicts.insert(3, r5)
    return Judged(verdicts, lat, res, grown + tail)


__all__ = ["TITLES", "Judged", "Stopped", "judge_soak", "latency_trends", "resource_trends", "warmup"]

"""An analysis as the suite's evidence: CaseResults, SuiteInfo, and the report files.

One :class:`~conformance.model.verdicts.CaseResult` per (clause, side) of the catalogue
(:mod:`.capture_catalogue`): its verdict is the worst of its findings, PASS when it judged
something and found nothing, SKIP when the capture had nothing for it to judge. The
message names the first finding and its frames; ``observed`` lists the findings kept,
worst first, with their frame numbers; ``sent_hex`` holds the robot's bytes and
``received_hex`` the box's. The latency plots ride on OBS-T1-box (every request) and
OBS-T2-box (every pose); the pose send-interval histogram on OBS-T2-robot.
"""

from __future__ import annotations

import dataclasses
import datetime as _dt
import math
from pathlib import Path
from typing import Any

from .. import __version__
from ..model.verdicts import VERDICT_ORDER, CaseResult, SuiteInfo, Verdict
from ..report import write_reports
from ..suite.record import CaseRecord
from .capture_catalogue import SPECS, spec_for
from .engine import Analysis
from .findings import ROBOT, Series, Tally

__all__ = ["build_cases", "describe_capture", "suite_info", "write_analysis"]

SHOWN = 8  # findings quoted per verdict in ``observed``
HISTOGRAM_BINS = 40

#: what each case judges, for "N <items> judged"
_ITEMS = {"A1": "request", "A2": "answer", "T1": "answer", "S1": "session", "E4": "session", "S5": "connection",
          "T2": "stream", "R1": "malformed request", "R6": "connection", "R7": "bad datagram", "S2": "CycleOn",
          "S3": "pose", "E2": "ProgIdx", "E3": "result request", "A4": "NONE", "A3": "answer", "F4": "frame"}


def _item(clause: str, side: str, n: int) -> str:
    word = _ITEMS.get(clause, "frame")
    if clause == "A1" and side == ROBOT:
        word = "follow-up request"
    return f"{n:,} {word}{'' if n == 1 else 's'}"


def _case(spec: CaseRecord, tally: Tally | None, analysis: Analysis) -> CaseResult:
    clause, side = spec.id.split("-")[1], spec.id.split("-")[2]
    case = CaseResult(spec.id, spec.title, spec.clauses, spec.level, Verdict.SKIP, requirement=spec.requirement,
                      expected=spec.expect, pcap=str(analysis.path))
    if tally is None or (not tally.checked and not tally.counts):
        case.message = (f"nothing in the capture to judge for {clause} on the {side} side"
                        + ("" if analysis.found else ": no iSight conversation"))
        case.observed = case.message
        _extras(case, tally, analysis)
        return case
    worst = tally.worst()
    lines: list[str] = []
    for verdict in VERDICT_ORDER:
        n = tally.counts.get(verdict, 0)
        if not n:
            continue
        kept = tally.kept.get(verdict, [])
        lines.append(f"{verdict.value} ({n:,}):")
        lines += [f"  {f.line()}" for f in kept[:SHOWN]]
        if n > min(len(kept), SHOWN):
            lines.append(f"  … and {n - min(len(kept), SHOWN):,} more")
    if tally.checked:
        lines.append(f"{_item(clause, side, tally.checked)} judged")
    lines += tally.notes
    case.observed = "\n".join(lines)
    if worst is None:
        case.verdict = Verdict.PASS
        case.message = f"{_item(clause, side, tally.checked)} judged; none breaks {clause}"
        if tally.notes and clause in ("T2", "S1", "E4"):
            case.message += f" ({tally.notes[0]})"
    else:
        case.verdict = worst
        first = tally.kept[worst][0]
        others = sum(tally.counts.values()) - 1
        case.message = f"{first.line()}" + (f" (and {others:,} more finding(s))" if others else "")
        case.sent_hex, case.received_hex = first.robot_hex, first.box_hex
        case.details["frames"] = sorted({n for f in tally.kept[worst] for n in f.frames if n})[:50]
    _extras(case, tally, analysis)
    return case


def _extras(case: CaseResult, tally: Tally | None, analysis: Analysis) -> None:
    ctx = analysis.ctx
    if tally is not None:
        case.details.update(tally.details)
    if case.id == "OBS-T1-box" and ctx.latency.n:
        _plot(case, ctx.latency, "every answered request but the poses (OBS-T2-box plots those)")
    elif case.id == "OBS-T2-box" and ctx.stream_plot is not None:
        _plot(case, ctx.stream_plot[2], f"the poses of {ctx.stream_plot[1]}, the stream with the highest latency")
    elif case.id == "OBS-T2-robot" and ctx.intervals.n:
        period = 1000.0 / ctx.profile.pose_rate_hz
        case.details["interval_histogram"] = {
            "values_ms": [round(v, 3) for v in ctx.intervals.sample], "bins": HISTOGRAM_BINS,
            "expected_ms": round(period, 3),
            "title": f"robot pose send intervals, at the capture ({ctx.intervals.n:,} intervals"
                     + (", evenly sampled" if ctx.intervals.n > len(ctx.intervals.sample) else "") + ")"}


def _plot(case: CaseResult, series: Series, what: str) -> None:
    values, per = series.plot_values()
    case.latencies_ms = [v if math.isfinite(v) else math.nan for v in values]
    case.details["latency"] = (f"{what}: {series.describe()}; mean {series.mean:.2f} ms"
                               + (f"; plotted as the minimum and maximum of every {per:,} answers" if per > 1 else ""))


def build_cases(analysis: Analysis) -> list[CaseResult]:
    tallies = analysis.ctx.findings.tallies
    cases = [_case(spec, tallies.get(key), analysis) for key, spec in SPECS.items()]
    for key in sorted(set(tallies) - set(SPECS)):  # a clause no spec names: never dropped
        cases.append(_case(spec_for(*key), tallies[key], analysis))
    return cases


def _when(ts: float | None) -> str:
    if ts is None:
        return "?"
    return _dt.datetime.fromtimestamp(ts, _dt.timezone.utc).strftime("%Y-%m-%d %H:%M:%S UTC")


def describe_capture(analysis: Analysis) -> str:
    s = analysis.ctx.stats
    span = (s.last_ts - s.first_ts) if s.first_ts is not None and s.last_ts is not None else 0.0
    parts = [f"capture {analysis.path.name} ({analysis.format}, {analysis.frames:,} frames over {span:.1f} s "
             f"from {_when(s.first_ts)})",
             f"robot(s) {', '.join(sorted(s.robots)) or 'none'}", f"box(es) {', '.join(sorted(s.boxes)) or 'none'}",
             f"{s.tcp_connections} TCP connection(s) in {s.sessions} session(s)"]
    if s.udp_conversations:
        parts.append(f"{s.udp_conversations} UDP conversation(s)")
    if s.gaps:
        parts.append(f"{s.gaps} gap(s) ({s.gap_bytes:,} bytes missing)")
    if s.midstart:
        parts.append(f"{s.midstart} connection(s) already open at the start")
    if s.open_at_end:
        parts.append(f"{s.open_at_end} still open at the end")
    if s.cut_frames or s.skipped_bytes:
        parts.append(f"not judged: {s.cut_frames} frame(s) cut by a gap or an end, {s.skipped_bytes:,} byte(s) before "
                     "the first whole frame of a direction")
    if s.conflicts:
        parts.append(f"{s.conflicts} retransmission(s) with bytes other than the first copy's")
    other = sum(s.skipped.values())
    if other:
        parts.append(f"{other:,} frame(s) not TCP/UDP over IP ("
                     + ", ".join(f"{n:,} {why}" for why, n in sorted(s.skipped.items(), key=lambda kv: -kv[1])[:4]) + ")")
    if s.truncated:
        parts.append(f"file cut short: {s.truncated}")
    return "; ".join(parts)


def suite_info(analysis: Analysis, cases: list[CaseResult], command: str = "") -> SuiteInfo:
    ctx = analysis.ctx
    s = ctx.stats
    ext = ctx.config.extension
    return SuiteInfo(
        version=__version__, started=_dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"),
        duration_s=round(analysis.seconds, 3), target=describe_capture(analysis), profile=ctx.profile.to_dict(),
        udp_target=f"{s.udp_conversations} UDP conversation(s) in the capture" if s.udp_conversations else None,
        extension=("per session: E4 when it uses ProgIdx or the result request, else S1" if ext is None
                   else "forced on (every session judged as E4)" if ext else "off (every session judged as S1)"),
        command=command, role="observed",
        cases_total=len(cases),
    )


def write_analysis(analysis: Analysis, report_dir: Path, command: str = "", acceptance: dict[str, Any] | None = None,
                   capture_copy: Path | None = None) -> tuple[SuiteInfo, list[CaseResult]]:
    """The reports of an analysis; with ``capture_copy`` (the capture copied into the package), the cases cite
    the copy, so the package holds the evidence its links name."""
    cases = build_cases(analysis)
    if capture_copy is not None:
        cases = [dataclasses.replace(c, pcap=str(capture_copy)) if c.pcap == str(analysis.path) else c for c in cases]
    suite = suite_info(analysis, cases, command)
    write_reports(report_dir, suite, cases, acceptance=acceptance)
    return suite, cases


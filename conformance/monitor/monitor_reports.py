"""The monitor's reports: analyze's cases, its root causes with counts, the faults and what the robot did.

``summary.json``, ``junit.xml`` and ``report.html`` are the suite's (written atomically
by :func:`conformance.report.write_reports`), their cases ``analyze``'s
(:func:`conformance.analyze.analysis_report.build_cases`: ``OBS-<clause>-box`` /
``OBS-<clause>-robot``), plus one INFORMATIONAL case per ``--fault`` spec
(``MON-FAULT-<n>``) listing its injections, what the robot did after each, and the box
findings the fault caused (not filed against the box). Root causes are the monitor's
deduplicated findings, worst first, each with its count and first/last seen.
``monitor.json`` holds the same root causes and faults as data, the ring's files with the
first frame number of each, the counts of the live view, and the monitor's own events.
"""

from __future__ import annotations

import datetime as _dt
import json
from pathlib import Path
from typing import Any

from ..analyze.analysis_report import build_cases, suite_info
from ..analyze.engine import Analysis
from ..model.verdicts import CaseResult, Level, RootCause, SuiteInfo, Verdict
from ..report import write_reports
from ..report.summary import atomic_write_bytes
from .hub import Hub
from .live_findings import Cause

__all__ = ["snapshot", "write_monitor_reports"]


def _analysis(hub: Hub) -> Analysis:
    ring = hub.ring
    path = ring.directory if ring is not None else Path("no-pcap")
    size = ring.disk_bytes() if ring is not None else 0
    ctx = hub.ctx
    if ctx.stats.first_ts is None:
        ctx.stats.first_ts = hub.started
    ctx.stats.last_ts = hub.clock()
    ctx.stats.frames = hub.wire.frames
    return Analysis(ctx, path, "pcapng ring" if ring is not None else "not recorded", size, hub.wire.frames,
                    hub.elapsed())


def _fault_cases(hub: Hub) -> list[CaseResult]:
    cases = []
    time_out = hub.reactions.time_out_ms
    excused = hub.findings.excused
    for n, fault in enumerate(hub.faults.faults, 1):
        injections = [i for i in hub.reactions.injections if i.spec == fault.spec]
        lines = [f"{fault.injected:,} injection(s) of {fault.seen:,} matching answer(s)"]
        for inj in injections:
            lines.append(f"#{inj.id} conn {inj.line}, frame {inj.frame}: {inj.what}; the robot: {inj.summary(time_out)}")
            lines += [f"    not filed against the box: {e}" for e in excused.get(inj.id, [])[:5]]
        if fault.injected > len(injections):
            lines.append(f"… {fault.injected - len(injections):,} more injection(s), counted, not followed")
        first = injections[0] if injections else None
        message = (f"injected {fault.injected:,}×: " + (f"{first.what}; the robot {first.summary(time_out)}"
                                                          if first else "no matching answer came"))
        case = CaseResult(f"MON-FAULT-{n}", f"injected fault {fault.spec}", (fault.clause,), Level.MAY,
                          Verdict.INFORMATIONAL, message=message,
                          requirement=f"rehearsal: the monitor makes the box's side break {fault.clause} on purpose "
                                      "and records what the robot does next",
                          expected="whatever the robot program is meant to do (its time_out, retries, reconnects)",
                          observed="\n".join(lines))
        case.details["injections"] = [i.to_dict(time_out) for i in injections]
        cases.append(case)
    return cases


def _root_causes(causes: list[Cause], cases: list[CaseResult]) -> list[RootCause]:
    by_id = {c.id: c for c in cases}
    out: list[RootCause] = []
    for cause in causes:
        if cause.verdict not in (Verdict.FAIL, Verdict.NON_STRICT, Verdict.ERROR):
            continue  # a root cause is a defect; INCONCLUSIVE ones stay in monitor.json
        rc = RootCause(f"RC{len(out) + 1}", (cause.clause,), f"{cause.side}: {cause.signature} ({cause.count:,}×)",
                       f"{cause.count:,} time(s), first seen {_iso(cause.first_seen)}, last seen "
                       f"{_iso(cause.last_seen)}; first: {cause.first.line()}"
                       + (f"; robot → box {cause.first.robot_hex}" if cause.first.robot_hex else "")
                       + (f"; box → robot {cause.first.box_hex}" if cause.first.box_hex else ""),
                       level=Level.MUST if cause.verdict is Verdict.FAIL else Level.SHOULD, kind=cause.side)
        case_id = f"OBS-{cause.clause}-{cause.side}"
        case = by_id.get(case_id)
        if case is not None:
            rc.cases.append(case_id)
            if case.root_cause is None and case.verdict is cause.verdict:
                case.root_cause = rc.id
        out.append(rc)
    return out


def _iso(t: float) -> str:
    return _dt.datetime.fromtimestamp(t, _dt.timezone.utc).isoformat(timespec="milliseconds")


def snapshot(hub: Hub, command: str = "") -> tuple[SuiteInfo, list[CaseResult], list[RootCause]]:
    analysis = _analysis(hub)
    cases = build_cases(analysis) + _fault_cases(hub)
    if hub.wire.judge_errors:
        cases.append(CaseResult("MON-JUDGE", "the monitor's judgement of every packet", ("F1",), Level.MUST,
                                Verdict.ERROR, message=f"the engine failed on {hub.wire.judge_errors:,} packet(s): "
                                f"{hub.wire.judge_error} (the suite's own fault, not the robot's or the box's; the "
                                "bytes were forwarded)"))
    suite = suite_info(analysis, cases, command)
    s = hub.settings
    suite.target = (f"live line: robots → monitor {s.listen[0]}:{s.listen[1]} → box {s.upstream[0]}:{s.upstream[1]}"
                    f"{' (and UDP)' if s.udp else ''}; {hub.connections:,} connection(s) in {hub.elapsed():.0f} s; "
                    f"{describe(hub)}; {suite.target}")
    suite.started = _iso(hub.started)
    roots = _root_causes(hub.findings.roots.ordered(), cases)
    return suite, cases, roots


def describe(hub: Hub) -> str:
    parts = []
    if hub.wire.judge_errors:
        parts.append(f"ERROR: the judgement failed on {hub.wire.judge_errors:,} packet(s) (the suite's own fault; "
                     f"the bytes were forwarded; first: {hub.wire.judge_error})")
    if hub.upstream_failures:
        parts.append(f"{hub.upstream_failures:,} connection(s) the box did not accept")
    if hub.reactions.total:
        parts.append(f"{hub.reactions.total:,} fault(s) injected (never blamed on the box; "
                     f"{hub.findings.excused_count:,} box finding(s) they caused set aside)")
    if hub.ring is not None:
        parts.append(f"pcapng ring in {hub.ring.directory} ({len(hub.ring.kept)} file(s), "
                     f"{hub.ring.disk_bytes() / 1e6:.1f} MB, {hub.ring.deleted} older file(s) deleted)"
                     + (f"; recording STOPPED: {hub.ring.error}" if hub.ring.error else ""))
    return "; ".join(parts) or "no pcap recorded"


def monitor_doc(hub: Hub) -> dict[str, Any]:
    ctx = hub.ctx
    return {
        "listen": list(hub.settings.listen), "upstream": list(hub.settings.upstream),
        "started": _iso(hub.started), "seconds": round(hub.elapsed(), 3),
        "connections": hub.connections, "open": len(hub.open), "sessions": ctx.stats.sessions,
        "packets": hub.wire.frames, "bytes": dict(hub.wire.bytes), "upstream_failures": hub.upstream_failures,
        "frames": dict(zip(("robot", "box", "poses"), hub.counts())),
        "latency_ms": {"n": ctx.latency.n, "p50": _num(ctx.latency.percentile(50)),
                       "p99": _num(ctx.latency.percentile(99))},
        "root_causes": [c.to_dict() for c in hub.findings.roots.ordered()],
        "faults": [{"spec": f.spec, "matching": f.seen, "injected": f.injected} for f in hub.faults.faults],
        "injections": [i.to_dict(hub.reactions.time_out_ms) for i in hub.reactions.injections],
        "excused_findings": hub.findings.excused_count,
        "judge_errors": hub.wire.judge_errors, "first_judge_error": hub.wire.judge_error,
        "ring": hub.ring.index() if hub.ring is not None else [],
        "ring_bytes": hub.ring.disk_bytes() if hub.ring is not None else 0,
        "ring_error": str(hub.ring.error) if hub.ring is not None and hub.ring.error else None,
        "events": list(hub.events),
        "alarms": [a.to_dict() for a in hub.alarms.all()],
        "alarms_active": len(hub.alarms.active),
        "alarms_raised": dict(hub.alarms.raised),
    }


def _num(v: float) -> float | None:
    return None if v != v else round(v, 3)


def write_monitor_reports(hub: Hub, report_dir: Path, command: str = "",
                          acceptance: dict[str, Any] | None = None) -> tuple[SuiteInfo, list[CaseResult]]:
    """Every report, each file written atomically (a checkpoint or the final one)."""
    suite, cases, roots = snapshot(hub, command)
    write_reports(report_dir, suite, cases, roots, acceptance=acceptance)
    text = json.dumps(monitor_doc(hub), indent=2, ensure_ascii=False) + "\n"
    atomic_write_bytes(report_dir / "monitor.json", text.encode("utf-8", "backslashreplace"))
    return suite, cases

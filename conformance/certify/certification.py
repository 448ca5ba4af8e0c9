"""One certification run: listen, let the robot play, judge, write the evidence.

:func:`certify` is the whole run as a coroutine (the CLI and the tests call it; a test
runs :class:`~conformance.endpoints.robot.RobotSession` on the same loop). It returns a
:class:`CertifyOutcome` with the cases and the exit status: 0 no FAIL/ERROR, 1 a FAIL
or ERROR (or the run was interrupted), 2 no robot connected within ``--wait``.
"""

from __future__ import annotations

import asyncio
import contextlib
import datetime as _dt
import os
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

from .. import __version__
from ..engine.rootcause import find_root_causes
from ..evidence.pcap import write_transcript
from ..harness.starvation import gauge, watch_loop
from ..harness.transcript import ConnectionInfo, Transcript, WireEvent
from ..model.exit_codes import EXIT_FAILED, EXIT_OK, EXIT_USAGE
from ..model.verdicts import CaseResult, RootCause, SuiteInfo
from ..observed.connections import SessionRecord
from ..report import write_reports
from .checks import extension_label, judge
from .listener import CertifyListener
from .records import CertifyConfig, RunRecord


class ListenError(OSError):
    """The suite cannot listen where it was told to (a usage error: exit 2)."""


@dataclass
class CertifyOutcome:
    exit_code: int
    reason: str  # one line
    run: RunRecord | None = None
    cases: list[CaseResult] = field(default_factory=list)
    suite: SuiteInfo | None = None
    reports: dict[str, Path] = field(default_factory=dict)
    root_causes: list[RootCause] = field(default_factory=list)


def robot_label(run: RunRecord) -> str:
    """``robot at HOST:PORT (client role)``: the robot's address on its first connection."""
    for session in run.sessions:
        for conn in session.conns:
            return f"robot at {conn.peer} (client role)"
    return "robot (client role): no connection"


def session_transcript(session: SessionRecord) -> Transcript:
    """Every connection of a session in one transcript (one pcap with all of them)."""
    merged = Transcript(case_id=f"session-{session.number}")
    events: list[WireEvent] = []
    for conn in session.conns:
        merged.connections[conn.number] = ConnectionInfo(conn.number, conn.transport, conn.local, conn.peer,
                                                         f"robot {conn.role} connection")
        events += [WireEvent(e.t, conn.number, e.kind, e.data, e.note) for e in conn.transcript.events]
    merged.events = sorted(events, key=lambda e: e.t)
    return merged


def write_pcaps(run: RunRecord) -> None:
    """Name each connection's pcap by its role and write one pcap per session."""
    pcap_dir = run.config.pcap_dir
    if pcap_dir is None:
        return
    for session in run.sessions:
        for conn in session.conns:
            if conn.pcap is not None and conn.pcap.exists() and conn.transport == "tcp":
                named = conn.pcap.with_name(f"{conn.pcap.stem}-{conn.role}.pcapng")
                with contextlib.suppress(OSError):
                    os.replace(conn.pcap, named)
                    conn.pcap = named
        if session.conns:
            session.pcap = write_transcript(session_transcript(session), pcap_dir / f"session-{session.number}.pcapng")


def suite_info(run: RunRecord, started: str) -> SuiteInfo:
    udp = sorted({str(c.peer) for s in run.sessions for c in s.conns if c.transport == "udp"})
    cfg = run.config
    return SuiteInfo(
        version=__version__, started=started, duration_s=round(run.t_end - run.t_start, 3), target=robot_label(run),
        profile=cfg.profile.to_dict(), udp_target=f"robot datagrams from {', '.join(udp)}" if udp else None,
        extension=extension_label(run), command=cfg.command, role="robot",
    )


async def certify(
    config: CertifyConfig,
    *,
    on_listening: Callable[[str], None] | None = None,
    on_event: Callable[[str], None] | None = None,
    listener_ready: Callable[[CertifyListener], None] | None = None,
) -> CertifyOutcome:
    """The run. Raises :class:`ListenError` when it cannot listen (a usage error for the CLI)."""
    listener = CertifyListener(config, on_event)
    try:
        await listener.start()
    except OSError as exc:
        raise ListenError(exc.errno, exc.strerror or str(exc)) from None
    started = _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds")
    if on_listening is not None:
        on_listening(listener.describe())
    if listener_ready is not None:
        listener_ready(listener)
    with gauge():  # the suite's own scheduling delay while it stamps the robot's frames (T2 on a loaded runner)
        stop_watch = watch_loop(asyncio.get_running_loop())
        try:
            run = await listener.run()
        finally:
            stop_watch()
    if not run.sessions:
        return CertifyOutcome(EXIT_USAGE, run.end_note or "no robot connected", run)
    await asyncio.to_thread(write_pcaps, run)
    cases = judge(run)
    causes = find_root_causes(cases)  # one defect that fails several cases (a stream left open: S5 and S1)
    suite = suite_info(run, started)
    outcome = CertifyOutcome(EXIT_OK, run.end_note, run, cases, suite, root_causes=causes)
    if config.report_dir is not None:
        await asyncio.to_thread(write_reports, config.report_dir, suite, cases, causes, None, config.acceptance)
        outcome.reports = {"HTML report": config.report_dir / "report.html",
                           "JSON summary": config.report_dir / "summary.json",
                           "JUnit": config.report_dir / "junit.xml"}
    if config.pcap_dir is not None:
        outcome.reports["pcaps"] = config.pcap_dir
    failing = [c for c in cases if c.verdict.failing]
    if run.end_reason == "interrupted":
        outcome.exit_code, outcome.reason = EXIT_FAILED, f"interrupted ({run.end_note}); the reports cover what was seen"
    elif failing:
        outcome.exit_code = EXIT_FAILED
        outcome.reason = f"{len(failing)} case(s) FAIL/ERROR: " + ", ".join(c.id for c in failing[:8])
    return outcome

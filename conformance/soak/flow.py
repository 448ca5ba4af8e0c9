"""A soak from start to end: the box, the extension, the report directory, the player, the evidence.

``run_soak(settings)`` returns the exit status: 0 nothing FAILed (findings may be listed), 1 a FAIL,
2 a usage error or an unreachable box, 3 the soak was cut short by SIGINT/SIGTERM (its evidence
written, marked incomplete).
"""

from __future__ import annotations

import asyncio
import contextlib
import datetime as _dt
import signal
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ..fuzz.box_process import BoxProcess
from ..harness.extension_probe import extension_for
from ..harness.target import Target, check_reachable
from ..harness.transcript import Transcript
from ..model.exit_codes import EXIT_FAILED, EXIT_INCOMPLETE, EXIT_OK, EXIT_USAGE
from ..report.rundirs import default_run_dirs
from .boxstart import bundled_command, start_box
from .document import build_document
from .evidence import EvidenceWriter
from .page import write_page
from .pcapring import PcapRing
from .player import SoakPlayer
from .progress import Progress
from .resources import BoxProbe, describe
from .settings import SoakSettings
from .verdicts import Judged


@dataclass
class Box:
    target: Target
    label: str
    process: BoxProcess | None
    probe: BoxProbe | None


def open_box(settings: SoakSettings) -> Box:
    """The box to soak (started when the settings say so); ValueError with one line when it cannot be."""
    process = None
    target = settings.target
    if settings.restart_cmd is not None:
        process, target = start_box(settings.restart_cmd, target)
        label = f"box started by {settings.restart_cmd!r} at {target}"
    elif target is None:
        process, target = start_box(bundled_command(settings.profile), None)
        label = f"bundled reference box at {target}"
    else:
        label = str(target)
    try:
        problem = check_reachable(target, settings.profile.time_out_s)
        if problem:
            raise ValueError(problem)
        pid = settings.box_pid
        if pid is None and process is not None and process.current is not None:
            pid = process.current.proc.pid
        probe = BoxProbe(pid) if pid is not None else None
    except ValueError:
        if process is not None:
            process.close()
        raise
    return Box(target, label, process, probe)


def _interrupt(signum: int, frame: object) -> None:
    raise KeyboardInterrupt  # SIGTERM before the soak's loop runs: the box the soak started is stopped too


def run_soak(settings: SoakSettings, command: str = "") -> int:
    previous = signal.signal(signal.SIGTERM, _interrupt)
    try:
        return _run_soak(settings, command)
    finally:
        signal.signal(signal.SIGTERM, previous)


def _run_soak(settings: SoakSettings, command: str) -> int:
    try:
        box = open_box(settings)
    except ValueError as exc:
        print(f"isight-conformance soak: {exc}", file=sys.stderr)
        return EXIT_USAGE
    try:
        return _soak(settings, box, command)
    finally:
        if box.process is not None:
            box.process.close()


def _soak(settings: SoakSettings, box: Box, command: str) -> int:
    extension, how = extension_for(settings.extension, box.target, settings.profile, Transcript())
    try:
        report_dir, _ = default_run_dirs(settings.report_dir, None, pcaps=False, prefix="soak-")
    except OSError as exc:
        print(f"isight-conformance soak: cannot create the report directory: {exc}", file=sys.stderr)
        return EXIT_USAGE
    started = _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds")
    progress = Progress(settings.duration_s, settings.quiet)
    player = SoakPlayer(settings, (box.target.host, box.target.port), extension, box.probe,
                        progress=progress.tick)
    box_info = describe(box.probe)
    session = "E4 (extension)" if extension else "S1"

    ring = None
    if settings.pcap_ring:
        ring = PcapRing(report_dir / "pcaps", box.target.port, settings.pcap_ring, settings.pcap_interface)
        ring.start(0)
        if ring.error:
            print(f"isight-conformance soak: no pcaps: {ring.error}", file=sys.stderr)

    def build(final: bool) -> tuple[dict[str, Any], Judged]:
        doc, judged = build_document(player, target=box.label, box=box_info, extension=how, started=started,
                                     command=command, final=final)
        doc["session"] = session
        doc["pcaps"] = ring.to_dict() if ring is not None else None
        if player.box_gone is not None and box.process is not None:
            words = box.process.last_words(wait_s=0.5)  # what the box wrote before it ended
            if words is not None:
                doc["box_last_words"] = {"summary": words.summary(), "tail": words.shown_tail()}
                last = next((line for line in reversed(words.tail.splitlines()) if line.strip()), "")
                if doc["stopped"] and last:
                    doc["stopped"]["reason"] += f"; its last line: {last.strip()[:200]}"
        return doc, judged

    writer = EvidenceWriter(report_dir, build, command, html=write_page)

    def on_window(row: Any) -> None:
        progress.window(row)
        if ring is not None:
            ring.rotate(row)
        writer.checkpoint()

    player.on_window = on_window
    if not settings.quiet:
        print(f"isight-conformance soak: {box.label}, {session} sessions, {settings.robots} robot(s), "
              f"windows of {settings.window_s:g} s, events {settings.events}; evidence in {report_dir}",
              file=sys.stderr)
    try:
        with progress:
            asyncio.run(_play(player))
    finally:
        if ring is not None:
            ring.close()
    doc = writer.write(final=True)
    return _finish(doc, report_dir, player)


async def _play(player: SoakPlayer) -> None:
    stop = asyncio.Event()
    loop = asyncio.get_running_loop()
    for sig in (signal.SIGINT, signal.SIGTERM):
        with contextlib.suppress(NotImplementedError, RuntimeError):
            loop.add_signal_handler(sig, stop.set)
    try:
        await player.run(stop)
    finally:
        for sig in (signal.SIGINT, signal.SIGTERM):
            with contextlib.suppress(NotImplementedError, RuntimeError):
                loop.remove_signal_handler(sig)
        signal.signal(signal.SIGTERM, _interrupt)  # asyncio left SIG_DFL: the last write must still happen


def _finish(doc: dict[str, Any] | None, report_dir: Path, player: SoakPlayer) -> int:
    if doc is None:
        return EXIT_FAILED
    for v in doc["verdicts"]:
        print(f"{v['clause']:<3} {v['verdict']:<13} {v['message']}")
    for finding in doc["findings"]:
        print(f"finding: {finding}")
    rss = doc.get("soak_rss_mb")
    tail = f"; the soak's own RSS {rss['first']:.1f} → {rss['last']:.1f} MB" if rss else ""
    print(f"{doc['overall']}: {doc['totals']['sessions']:,} sessions in {doc['elapsed_s']:.0f} s, ended by "
          f"{player.ended_by}{tail}; {report_dir / 'report.html'}")
    if player.ended_by == "signal":
        return EXIT_INCOMPLETE
    return EXIT_FAILED if doc["overall"] == "FAIL" else EXIT_OK


__all__ = ["open_box", "run_soak"]

"""``isight-conformance analyze CAPTURE``: judge a capture of real robot ↔ box traffic.

Exit status, as ``run``: 0 no FAIL/ERROR, 1 a FAIL or ERROR, 2 a usage error or a file
that is not a whole capture (empty, cut short, not pcap/pcapng) or holds no iSight
traffic. See docs/ANALYZE.md.
"""

from __future__ import annotations

import argparse
import datetime as _dt
import os
import shlex
import shutil
import sys
from pathlib import Path

from ..acceptance.record import add_acceptance_options, from_args, seal_package
from ..analyze.analysis_context import AnalyzeConfig
from ..analyze.analysis_report import write_analysis
from ..analyze.engine import CaptureError, analyze
from ..i18n import N_, _
from ..model.exit_codes import EXIT_FAILED, EXIT_OK, EXIT_USAGE
from ..runtime.profile_options import profile_from_options
from .options import add_profile_group
from .registry import Command

__all__ = ["COMMAND", "config_from_args", "main_analyze"]

#: captures at least this large get a progress bar (on a terminal)
PROGRESS_FROM = 4 << 20


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("capture", type=Path, metavar="CAPTURE", help=_("the capture file (pcap or pcapng, may be .gz)"))
    found = p.add_argument_group("finding the iSight traffic")
    found.add_argument("--port", type=int, action="append", default=None, metavar="N",
                       help=_("iSight's TCP/UDP port (repeatable; default: 9004): the side on it is the box"))
    found.add_argument("--no-heuristic", action="store_true",
                       help=_("only conversations on --port; by default conversations on other ports that carry "
                            "iSight frames are found by their content, as the Wireshark dissector does"))
    judge = p.add_argument_group("judgement")
    judge.add_argument("--extension", action=argparse.BooleanOptionalAction, default=None,
                       help=_("[E4] judge every session as the revision's (--extension) or as S1 (--no-extension); "
                            "default: a session with ProgIdx or a result request is E4"))
    judge.add_argument("--rate-tolerance", type=float, default=10.0, metavar="PCT",
                       help=_("[T2] robot: mean and per-second stream rate within PCT %% of --pose-rate (default: 10)"))
    judge.add_argument("--jitter-tolerance", type=float, default=50.0, metavar="PCT",
                       help=_("[T2] robot: p99 |interval - 1/rate| within PCT %% of the period (default: 50)"))
    judge.add_argument("--linger", type=float, default=5.0, metavar="S",
                       help=_("[S5] robot: seconds a connection may stay open after the command connection closed "
                            "(default: 5)"))
    judge.add_argument("--accept-truncated", action="store_true",
                       help=_("judge a capture file that is cut short (up to the cut) instead of refusing it"))
    out = p.add_argument_group("reports")
    out.add_argument("--report-dir", type=Path, default=None, metavar="DIR",
                     help=_("summary.json, junit.xml, report.html (default: reports/analyze-<timestamp>)"))
    out.add_argument("--quiet", action="store_true", help=_("no progress bar"))
    add_acceptance_options(p.add_argument_group(_("acceptance (one package per run: see docs/REPORTS.md)")).add_argument,
                           declared=False)
    add_profile_group(p, "profile (--pose-rate is the rate the robot declares; --crc is the UDP CRC)")


def config_from_args(args: argparse.Namespace) -> AnalyzeConfig:
    return AnalyzeConfig(
        profile=profile_from_options(args), ports=tuple(dict.fromkeys(args.port or [9004])),
        heuristic=not args.no_heuristic,
        crc_stated=getattr(args, "profile_crc", None) is not None or getattr(args, "profile_crc_byte_order", None)
        is not None,
        extension=args.extension, rate_tolerance=args.rate_tolerance / 100.0,
        jitter_tolerance=args.jitter_tolerance / 100.0, linger_s=args.linger, accept_truncated=args.accept_truncated,
    )


def package_capture(capture: Path, report_dir: Path) -> Path:
    """``--report-dir DIR``: the capture judged, copied to ``DIR/capture/`` (the package holds its evidence)."""
    folder = report_dir / "capture"
    folder.mkdir(parents=True, exist_ok=True)
    target = folder / capture.name
    if not target.exists() or not os.path.samefile(capture, target):
        tmp = folder / f".{capture.name}.tmp"
        shutil.copyfile(capture, tmp)
        os.replace(tmp, target)
    return target


def main_analyze(args: argparse.Namespace) -> int:
    from rich.console import Console

    from ..report.terminal import print_final_table

    name = "isight-conformance analyze"
    try:
        config = config_from_args(args)
        acceptance = from_args(args)
    except ValueError as exc:
        print(f"{name}: {exc}", file=sys.stderr)
        return EXIT_USAGE
    err = Console(stderr=True)
    bar = None
    try:
        if not args.quiet and err.is_terminal and args.capture.is_file() and args.capture.stat().st_size >= PROGRESS_FROM:
            from rich.progress import BarColumn, DownloadColumn, Progress, TimeRemainingColumn

            bar = Progress("[progress.description]{task.description}", BarColumn(), DownloadColumn(),
                           TimeRemainingColumn(), console=err, transient=True)
            bar.start()
            task = bar.add_task(f"analysing {args.capture.name}", total=args.capture.stat().st_size)
            analysis = analyze(args.capture, config, lambda done, total: bar.update(task, completed=done))
        else:
            analysis = analyze(args.capture, config)
    except CaptureError as exc:
        print(f"{name}: {exc}", file=sys.stderr)
        return EXIT_USAGE
    finally:
        if bar is not None:
            bar.stop()
    if not analysis.found:
        ports = ", ".join(map(str, config.ports))
        print(f"{name}: {args.capture}: no iSight traffic in {analysis.frames:,} frames (no conversation on port "
              f"{ports}{'' if config.heuristic else ''} or carrying iSight frames); try --port", file=sys.stderr)
        return EXIT_USAGE
    report_dir = args.report_dir or Path("reports") / f"analyze-{_dt.datetime.now().strftime('%Y%m%d-%H%M%S')}"
    command = " ".join(shlex.quote(a) for a in sys.argv)
    try:
        copy = package_capture(args.capture, report_dir) if args.report_dir else None
        suite, cases = write_analysis(analysis, report_dir, command, acceptance.to_dict(), copy)
        sealed = seal_package(report_dir, acceptance)  # the package's manifest, written last
    except OSError as exc:
        print(f"{name}: cannot write the reports: {exc.filename or report_dir}: {exc.strerror or exc}",
              file=sys.stderr)
        return EXIT_USAGE
    print_final_table(suite, cases, Console(), reports={"HTML report": report_dir / "report.html",
                                                       "JSON summary": report_dir / "summary.json",
                                                       "JUnit": report_dir / "junit.xml",
                                                       **({"capture": copy} if copy else {}),
                                                       "manifest": report_dir / "manifest.json"})
    print(f"{_('manifest sha256')}: {sealed}")
    failing = [c for c in cases if c.verdict.failing]
    if failing:
        print(f"{name}: {len(failing)} case(s) FAIL/ERROR: " + ", ".join(c.id for c in failing[:8]), file=sys.stderr)
        return EXIT_FAILED
    return EXIT_OK


COMMAND = Command(
    "analyze", N_("judge a capture (pcap/pcapng) of real robot <-> box traffic against PROTOCOL.md, both roles"), add_arguments, main_analyze,
    description=N_("Judge a capture of real robot <-> AI Box traffic (tcpdump on a mirror port, Wireshark on the box) "
        "against PROTOCOL.md's clauses, both roles, and write summary.json (suite.role = observed), junit.xml and "
        "report.html. Every finding names the capture's frame numbers. Exit status: 0 no FAIL/ERROR, 1 FAIL/ERROR, "
        "2 usage error, a file that is not a whole capture, or no iSight traffic in it. See docs/ANALYZE.md."), lang=True,
)

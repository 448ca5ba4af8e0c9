"""``isight-conformance monitor --listen HOST:PORT --upstream BOX:PORT``: judge a live robot ↔ box line in-line.

Exit status: 0 no FAIL/ERROR, 1 a FAIL or ERROR, 2 a usage error or the monitor cannot
listen. See docs/MONITOR.md.
"""

from __future__ import annotations

import argparse
import dataclasses
import shlex
import sys
from pathlib import Path

from ..acceptance.record import add_acceptance_options, from_args, seal_package
from ..harness.target import Target
from ..i18n import N_, _
from ..model.exit_codes import EXIT_FAILED, EXIT_OK, EXIT_USAGE
from ..monitor.hub import MonitorSettings
from ..report.rundirs import default_run_dirs, drop_if_empty
from .analyze import config_from_args
from .options import add_profile_group, parse_listen
from .registry import Command

__all__ = ["COMMAND", "main_monitor"]

NAME = "isight-conformance monitor"


def add_arguments(p: argparse.ArgumentParser) -> None:
    net = p.add_argument_group(_("the line"))
    net.add_argument("--listen", required=True, metavar="HOST:PORT",
                     help=_("where the robot connects (the address in its $HOSTC_CFG; port 0 picks a free one)"))
    net.add_argument("--upstream", required=True, metavar="BOX_HOST:PORT", help=_("the AI Box"))
    net.add_argument("--udp", action="store_true", help=_("forward UDP datagrams on the same port too"))
    net.add_argument("--connect-timeout", type=float, default=5.0, metavar="S",
                     help=_("seconds the box has to accept a connection before the robot's is reset (default: 5)"))
    net.add_argument("--duration", type=float, default=0.0, metavar="S",
                     help=_("stop after S seconds (default: run until SIGINT/SIGTERM/SIGHUP)"))
    faults = p.add_argument_group(_("fault injection (on the box's side; see docs/MONITOR.md)"))
    faults.add_argument("--fault", action="append", default=[], metavar="SPEC",
                        help=_("KIND:ACTION[:ARG][,every=N|,p=P][,count=K][,after=S]: delay:CYCLE_ON:6000, "
                             "drop:POSE,every=10, error:CYCLE_ON:1, corrupt:CYCLE_OFF:check, close:CYCLE_OFF, "
                             "stall:any:2000 (repeatable)"))
    faults.add_argument("--seed", type=int, default=0, metavar="N", help=_("seed for p= faults (default: 0)"))
    out = p.add_argument_group(_("evidence"))
    out.add_argument("--report-dir", type=Path, default=None, metavar="DIR",
                     help=_("summary.json, junit.xml, report.html, monitor.json (default: reports/monitor-<timestamp>)"))
    out.add_argument("--pcap-dir", type=Path, default=None, metavar="DIR",
                     help=_("the pcapng ring (default: pcaps/monitor-<timestamp>)"))
    out.add_argument("--no-pcap", action="store_true", help=_("record no pcapng"))
    out.add_argument("--ring", type=int, default=10, metavar="N", help=_("keep the newest N pcapng files (default: 10)"))
    out.add_argument("--ring-mb", type=float, default=100.0, metavar="M",
                     help=_("start a new pcapng file when the current one reaches M MB (default: 100)"))
    out.add_argument("--checkpoint", type=float, default=10.0, metavar="MINUTES",
                     help=_("write the reports every MINUTES minutes too; 0: only on stop (default: 10)"))
    out.add_argument("--quiet", action="store_true", help=_("findings only: no live panel, no status lines"))
    live = p.add_argument_group(_("plant monitoring (see docs/MONITOR.md)"))
    live.add_argument("--metrics", metavar="HOST:PORT", default=None,
                      help=_("serve Prometheus metrics at http://HOST:PORT/metrics (loopback unless --allow-remote)"))
    live.add_argument("--http", metavar="HOST:PORT", default=None,
                      help=_("serve the live page at http://HOST:PORT/ (loopback unless --allow-remote)"))
    live.add_argument("--allow-remote", action="store_true",
                      help=_("let --metrics and --http bind a non-loopback address: they have no authentication "
                             "and the page serves the ring's pcapng files"))
    judge = p.add_argument_group(_("judgement (as analyze)"))
    judge.add_argument("--extension", action=argparse.BooleanOptionalAction, default=None,
                       help=_("[E4] judge every session as the revision's / as S1; default: by what the session uses"))
    judge.add_argument("--rate-tolerance", type=float, default=10.0, metavar="PCT", help=_("[T2] robot (default: 10)"))
    judge.add_argument("--jitter-tolerance", type=float, default=50.0, metavar="PCT", help=_("[T2] robot (default: 50)"))
    judge.add_argument("--linger", type=float, default=5.0, metavar="S", help=_("[S5] robot (default: 5)"))
    add_profile_group(p, _("profile"))
    add_acceptance_options(p.add_argument_group(_("acceptance (one package per run: see docs/REPORTS.md)")).add_argument,
                           declared=False)


def settings_from_args(args: argparse.Namespace, pcap_dir: Path | None) -> MonitorSettings:
    listen = parse_listen(args.listen)
    up = Target.parse(args.upstream)
    if not 0 < up.port <= 65535:
        raise ValueError(f"bad --upstream {args.upstream!r}: the port must be 1..65535")
    args.port, args.no_heuristic, args.accept_truncated = [up.port], True, False
    config = config_from_args(args)
    if args.ring < 1 or not 0 < args.ring_mb <= 1 << 20:
        raise ValueError("--ring must be >= 1 and --ring-mb in (0, 1048576]")
    if args.checkpoint < 0 or args.duration < 0 or not 0 < args.connect_timeout <= 3600:
        raise ValueError("--checkpoint and --duration must be >= 0, --connect-timeout in (0, 3600]")
    settings = MonitorSettings(listen, (up.host, up.port), config, pcap_dir, args.ring, args.ring_mb,
                               list(args.fault), args.seed, args.udp, args.connect_timeout,
                               _served("--metrics", args.metrics, args.allow_remote),
                               _served("--http", args.http, args.allow_remote))
    from ..monitor.faults import FaultPlan

    FaultPlan(settings.faults)  # a malformed spec is a usage error now, not later
    return settings


def _served(option: str, value: str | None, allow_remote: bool) -> tuple[str, int] | None:
    """--metrics / --http HOST:PORT, loopback unless --allow-remote; ValueError (one line) otherwise."""
    if value is None:
        return None
    from ..monitor.webserve import check_bind

    try:
        address = parse_listen(value)
    except ValueError as exc:
        raise ValueError(str(exc).replace("--listen", option)) from None
    check_bind(option, address[0], allow_remote)
    return address


def main_monitor(args: argparse.Namespace) -> int:
    from rich.console import Console

    from ..monitor.monitor_loop import ListenError, monitor_main
    from ..monitor.view import View
    from ..report.terminal import print_final_table

    try:
        settings_from_args(args, None)
        report_dir, pcap_dir = default_run_dirs(args.report_dir, args.pcap_dir, not args.no_pcap, prefix="monitor-")
        acceptance = from_args(args)
        settings = dataclasses.replace(settings_from_args(args, pcap_dir), acceptance=acceptance.to_dict())
    except (ValueError, OSError) as exc:
        print(f"{NAME}: {exc}", file=sys.stderr)
        return EXIT_USAGE
    view = View(sys.stdout, sys.stdout.isatty(), args.quiet)
    command = " ".join(shlex.quote(a) for a in sys.argv)
    try:
        outcome = monitor_main(settings, report_dir, view, command, args.checkpoint * 60.0, args.duration)
    except ListenError as exc:
        drop_if_empty(report_dir if args.report_dir is None else None, pcap_dir if args.pcap_dir is None else None)
        print(f"{NAME}: cannot listen on {args.listen}: {exc.strerror or exc}", file=sys.stderr)
        return EXIT_USAGE
    except OSError as exc:
        print(f"{NAME}: {exc.filename or ''}: {exc.strerror or exc}", file=sys.stderr)
        return EXIT_USAGE
    sealed = seal_package(report_dir, acceptance)  # the package's manifest, after monitor.json
    print_final_table(outcome.suite, outcome.cases, Console(), reports={
        "HTML report": report_dir / "report.html", "JSON summary": report_dir / "summary.json",
        "JUnit": report_dir / "junit.xml", "monitor.json": report_dir / "monitor.json",
        **({"manifest": report_dir / "manifest.json"} if sealed else {})})
    if sealed:
        print(f"{_('manifest sha256')}: {sealed}")
    failing = [c for c in outcome.cases if c.verdict.failing]
    if failing:
        print(f"{NAME}: {len(failing)} case(s) FAIL/ERROR: " + ", ".join(c.id for c in failing[:8]), file=sys.stderr)
        return EXIT_FAILED
    return EXIT_OK


COMMAND = Command(
    "monitor", N_("sit in-line between a robot and its AI Box: forward every byte, judge both sides live, record a "
             "pcapng ring, inject protocol-aware faults"), add_arguments, main_monitor,
    description=N_("Listen for the robot (point its $HOSTC_CFG at this PC), open a connection to the box for each "
        "robot connection and pass the bytes on unchanged both ways, judging both sides live with analyze's engine. "
        "The first line on stdout is 'listening tcp HOST:PORT [udp HOST:PORT] -> upstream HOST:PORT'. Runs until "
        "SIGINT, SIGTERM or SIGHUP (or --duration), then writes summary.json, junit.xml, report.html and monitor.json. "
        "Exit status: 0 no FAIL/ERROR, 1 FAIL/ERROR, 2 usage error or cannot listen. See docs/MONITOR.md."), lang=True,
)

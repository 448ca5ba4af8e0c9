"""The ``soak`` command: production played against a box for hours, its latency and resources
judged as trends (:mod:`conformance.soak`; docs/SOAK.md).

Exit status: 0 nothing FAILed (findings may be listed), 1 a FAIL, 2 usage error or unreachable box,
3 cut short by SIGINT/SIGTERM (the evidence written so far is kept, marked incomplete).
"""

from __future__ import annotations

import argparse
import shlex
import sys
from pathlib import Path

from ..harness.target import Target
from ..i18n import N_, _
from ..model.exit_codes import EXIT_USAGE
from ..protocol import DEFAULT_PORT
from ..runtime.profile_options import profile_from_options
from ..soak.duration import parse_span
from ..soak.settings import EVENT_KINDS, SoakSettings, default_window, parse_events, parse_kinds, parse_window
from .options import add_profile_group
from .registry import Command


def add_arguments(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group("soak")
    g.add_argument("--target", metavar="HOST:PORT", help=_("the AI Box (default: start the bundled reference box)"))
    g.add_argument("--duration", required=True, metavar="SPAN", help=_("how long to soak: 30s, 90m, 2h, 8h"))
    g.add_argument("--window", default=None, metavar="SPAN",
                   help=_("one window of statistics (default: 60s, or a tenth of a soak shorter than 10 minutes)"))
    g.add_argument("--robots", type=int, default=1, metavar="N", help=_("robots playing sessions at once (default: 1)"))
    g.add_argument("--cycle-s", type=float, default=5.0, metavar="S",
                   help=_("the primer trajectory of each session, in seconds (default: 5)"))
    g.add_argument("--events", default="0", metavar="RATE",
                   help=_("planted events: N/h, N/min, or a share of sessions such as 0.1 (default: 0, none)"))
    g.add_argument("--event-kinds", default=",".join(EVENT_KINDS), metavar="LIST",
                   help=_("which events, taking turns (default: vanish,reset,stall,burst)"))
    g.add_argument("--stall-s", type=float, default=3.0, metavar="S",
                   help=_("how long a stalled stream stays silent (default: 3)"))
    g.add_argument("--burst", type=int, default=10, metavar="N",
                   help=_("connections in a reconnect burst (default: 10)"))
    g.add_argument("--ghost-hold", default="120s", metavar="SPAN",
                   help=_("how long a vanished robot's connections stay open before the soak resets them (default: 120s)"))
    box = g.add_mutually_exclusive_group()
    box.add_argument("--box-pid", type=int, metavar="PID", help=_("the box's process on this host: its RSS, fds, "
                     "threads and CPU are watched"))
    box.add_argument("--restart-cmd", metavar="CMD", help=_("start the box with this shell command and watch it "
                     "(its address from --target or its 'listening tcp HOST:PORT' line)"))
    g.add_argument("--report-dir", metavar="DIR", help=_("where soak.json, summary.json, junit.xml and report.html "
                   "go (default: reports/soak-<timestamp>)"))
    g.add_argument("--pcap-ring", type=int, default=0, metavar="N",
                   help=_("live pcaps of the newest N windows, and of every window with a finding, in DIR/pcaps "
                          "(needs root or CAP_NET_RAW; default: 0, none)"))
    g.add_argument("--pcap-interface", default="lo", metavar="IFACE",
                   help=_("the interface the pcaps are captured on (default: lo)"))
    g.add_argument("--seed", type=int, default=0, help=_("seed of the event plan (default: 0)"))
    g.add_argument("--extension", choices=("auto", "on", "off"), default="auto",
                   help=_("extension E (E4 sessions): detect (auto, default), or force on/off"))
    g.add_argument("--quiet", action="store_true", help=_("no progress line and no line per window"))
    add_profile_group(p)


def settings_from(args: argparse.Namespace) -> SoakSettings:
    """The settings the options ask for; ValueError with one line otherwise."""
    duration = parse_span(args.duration, "--duration")
    return SoakSettings(
        duration_s=duration, target=Target.parse(args.target, DEFAULT_PORT) if args.target else None,
        window_s=parse_window(args.window) if args.window else default_window(duration), robots=args.robots,
        cycle_s=args.cycle_s,
        events=parse_events(args.events), event_kinds=parse_kinds(args.event_kinds), stall_s=args.stall_s,
        burst_size=args.burst, ghost_hold_s=parse_span(args.ghost_hold, "--ghost-hold", shortest_s=0.0),
        box_pid=args.box_pid, restart_cmd=args.restart_cmd,
        report_dir=Path(args.report_dir) if args.report_dir else None, seed=args.seed,
        profile=profile_from_options(args), extension=args.extension, quiet=args.quiet,
        pcap_ring=args.pcap_ring, pcap_interface=args.pcap_interface,
    )


def main_soak(args: argparse.Namespace) -> int:
    try:
        settings = settings_from(args)
    except ValueError as exc:
        print(f"isight-conformance soak: {exc}", file=sys.stderr)
        return EXIT_USAGE
    from ..soak.flow import run_soak  # the player's imports only when a soak runs

    return run_soak(settings, "isight-conformance soak " + " ".join(shlex.quote(a) for a in sys.argv[2:]))


COMMAND = Command(
    "soak", N_("play production against a box for hours and judge its latency and resources as trends"),
    add_arguments, main_soak,
    description=N_("Canonical sessions back to back (E4 where the box implements it), planted events (a robot that "
                   "vanishes, a reset, a stalled stream, a reconnect burst), statistics per window, and trends judged "
                   "with Theil-Sen and Mann-Kendall. Exit status: 0 no FAIL, 1 FAIL, 2 usage error, 3 cut short."),
    # no --lang: the soak's verdicts and report.html are English for now (its help follows the locale)
    lang=False,
)

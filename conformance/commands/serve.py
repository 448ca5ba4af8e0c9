"""The ``serve`` command's parser and handler: the reference box (:mod:`conformance.endpoints.serve`)
in the foreground until SIGINT/SIGTERM."""

from __future__ import annotations

import argparse
import sys

from ..endpoints.behaviour import BoxConfig
from ..endpoints.serve import main_serve
from ..i18n import N_, _
from ..model.exit_codes import EXIT_FAILED
from ..protocol.answers import SENDABLE_RESULTS
from ..runtime.profile_options import profile_from_options
from .options import add_profile_group
from .registry import Command


def add_arguments(p: argparse.ArgumentParser) -> None:
    net = p.add_argument_group("network")
    net.add_argument("--host", default="127.0.0.1", help=_("address to listen on (default: 127.0.0.1)"))
    net.add_argument("--port", type=int, default=9004, help=_("TCP (and UDP) port; 0 picks a free one (default: 9004)"))
    net.add_argument("--udp-port", type=int, default=None, metavar="PORT",
                     help=_("UDP port, if not the TCP port (0 picks a free one)"))
    net.add_argument("--no-udp", action="store_true", help=_("serve TCP only"))
    net.add_argument("--max-connections", type=int, default=2000, metavar="N",
                     help=_("[R5] at most N TCP connections; past it the stalest is evicted (default: 2000)"))
    net.add_argument("--idle-timeout", type=float, default=300.0, metavar="S",
                     help=_("[R5] close a connection silent for S seconds; 0 = never (default: 300)"))
    net.add_argument("--loop", choices=("asyncio", "uvloop"), default="asyncio",
                     help=_("event loop (uvloop only if installed; default: asyncio)"))
    net.add_argument("--log", metavar="FILE", help=_("append every frame in and out to FILE as JSON lines"))
    knobs = p.add_argument_group("box behaviour")
    knobs.add_argument("--not-ready", action="store_true", help=_("[S2] answer CycleOn with 0001"))
    knobs.add_argument("--cycle-off-fails", action="store_true", help=_("[A3] answer CycleOff with 0002"))
    knobs.add_argument("--latency-ms", type=float, default=0.0, metavar="MS",
                       help=_("[T1] delay every answer by MS milliseconds (default: 0)"))
    knobs.add_argument("--vision-result", type=int, default=1, choices=SENDABLE_RESULTS, metavar="CODE",
                       help=_("[E3] ResultCode answered to a result request: 1, 2, 10, 20, 202, 400 or 409 (default: 1)"))
    knobs.add_argument("--progidx-conflict-box", action="store_true", help=_("[E2] answer ProgIdx with 409"))
    knobs.add_argument("--no-extension", action="store_true",
                       help=_("[E] do not implement actions 26/27 (treated as unknown actions: silence)"))
    knobs.add_argument("--close-on-garbage", action="store_true",
                       help=_("[A5] close a connection that sends bytes that are not a request (default: stay silent)"))
    add_profile_group(p)


def main_serve_command(args: argparse.Namespace) -> int:
    config = BoxConfig(
        profile=profile_from_options(args),
        not_ready=args.not_ready,
        cycle_off_fails=args.cycle_off_fails,
        latency_ms=args.latency_ms,
        vision_result=args.vision_result,
        progidx_conflict=args.progidx_conflict_box,
        extension=not args.no_extension,
        on_garbage="close" if args.close_on_garbage else "silent",
    )
    try:
        return main_serve(
            config, loop=args.loop, host=args.host, port=args.port, udp=not args.no_udp, udp_port=args.udp_port,
            max_connections=args.max_connections, idle_timeout=args.idle_timeout, log=args.log,
        )
    except OSError as exc:
        print(f"isight-conformance serve: {exc}", file=sys.stderr)
        return EXIT_FAILED


COMMAND = Command(
    "serve", N_("run the reference AI Box (TCP and UDP on one port) until SIGINT/SIGTERM"), add_arguments,
    main_serve_command,
    description=N_("Run the reference AI Box. The first line on stdout is "
        "'listening tcp HOST:PORT udp HOST:PORT' (useful with --port 0)."),
)

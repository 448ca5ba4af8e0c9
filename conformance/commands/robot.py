"""The ``robot`` command: play the canonical robot session against a box (its parser and handler)."""

from __future__ import annotations

import argparse
import sys

from ..endpoints.loop import new_event_loop
from ..endpoints.robot import RobotSession, run_robot
from ..i18n import N_, _
from ..runtime.profile_options import profile_from_options
from .options import add_profile_group
from .registry import Command


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--target", required=True, metavar="HOST:PORT", help=_("the box's command connection address"))
    p.add_argument("--stream-target", metavar="HOST:PORT", help=_("the stream connection's address (default: --target)"))
    p.add_argument("--duration", type=float, default=2.0, metavar="S",
                   help=_("seconds of primer trajectory between CycleOn and CycleOff (default: 2)"))
    p.add_argument("--extension", action="store_true",
                   help=_("[E4] play the revision's session: ProgIdx first, result request at the end"))
    p.add_argument("--program-index", type=int, default=1, metavar="N", help=_("[E2] program index to send (default: 1)"))
    p.add_argument("--result-wait", type=float, default=1.0, metavar="S",
                   help=_("[E4] wait between Send_Pos_Off and the result request (default: 1)"))
    p.add_argument("--ping", action="store_true", help=_("send action 00 after connecting (the optional ping)"))
    p.add_argument("--loop", choices=("asyncio", "uvloop"), default="asyncio", help=_("event loop (default: asyncio)"))
    p.add_argument("-q", "--quiet", action="store_true", help=_("print the summary only, not the timeline"))
    add_profile_group(p)


def main_robot(args: argparse.Namespace) -> int:
    new_event_loop(args.loop).close()  # an unavailable loop is a usage error (exit 2)
    session = RobotSession(
        args.target, profile_from_options(args), stream_target=args.stream_target, duration=args.duration,
        extension=args.extension, ping=args.ping, program_index=args.program_index, result_wait=args.result_wait,
    )
    result = run_robot(session, args.loop)
    if not args.quiet:
        print(result.format_timeline())
        print()
    print(result.format_summary())
    if not result.ok:
        print(f"isight-conformance robot: {result.reason}", file=sys.stderr)
    return result.exit_code


COMMAND = Command(
    "robot", N_("play the canonical robot session (S1, or E4 with --extension) against a box"), add_arguments, main_robot,
    description=N_("Play the canonical robot session against a box and print a timeline and a summary. "
        "Exit status: 0 clean session, 1 the box broke the protocol, 3 box not ready (CycleOn 0001 / ProgIdx 409), "
        "4 no answer within time_out, 5 connection refused or closed, 2 bad arguments."),
)

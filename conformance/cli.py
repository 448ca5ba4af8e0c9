"""The ``isight-conformance`` command.

Subcommands that a later milestone fills in say so in ``--help`` and exit with
status 2 and one clear line; they never pretend to have run.
"""

from __future__ import annotations

import argparse
import os
import sys
from collections.abc import Sequence

from . import __version__, clauses_cli, wireshark_cli
from .analyze import cli as analyze_cli
from .monitor import cli as monitor_cli
from .options import add_profile_options, profile_from_options
from .protocol import (
    ProtocolError,
    TransferType,
    Transport,
    parse_frame,
)
from .report import diff_cli

#: subcommand -> (help, the issue that delivers it)
PLANNED: dict[str, tuple[str, str]] = {}


def _decode(args: argparse.Namespace) -> int:
    try:
        data = bytes.fromhex(args.hex.replace(":", "").replace(" ", ""))
    except ValueError:
        print(f"isight-conformance decode: not hex: {args.hex!r}", file=sys.stderr)
        return 2
    profile = profile_from_options(args)
    expect = {"robot-to-box": TransferType.ROBOT_TO_BOX, "box-to-robot": TransferType.BOX_TO_ROBOT}.get(args.direction)
    transport = Transport.UDP if args.udp else Transport.TCP
    try:
        frame = parse_frame(data, profile, transport, expect)
    except ProtocolError as exc:
        print(f"invalid: {exc}")
        return 1
    print(f"valid: {frame.describe()}")
    for block in frame.blocks:
        print(f"  {block}")
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="isight-conformance",
        description="Conformance and fuzz test suite for the iSight socket protocol (FANUC robot <-> AI Box).",
    )
    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")

    dec = sub.add_parser("decode", help="decode one frame given as hex and name the clause it breaks")
    dec.add_argument("hex", help="the frame's bytes as hex, e.g. fefe000101000000000000000000")
    dec.add_argument("--udp", action="store_true", help="the frame is a UDP datagram (check the CRC)")
    dec.add_argument("--direction", choices=("robot-to-box", "box-to-robot", "any"), default="any")
    group = dec.add_argument_group("profile")
    add_profile_options(group.add_argument)
    dec.set_defaults(func=_decode)

    _add_serve(sub)
    _add_robot(sub)
    _add_certify_robot(sub)

    from .runner import add_run_arguments, main_run

    run = sub.add_parser(
        "run",
        help="test an AI Box against PROTOCOL.md and write summary.json, junit.xml, report.html and pcaps",
        description="Run the conformance suite against a box (or, with no --target, the bundled reference box). "
        "Exit status: 0 no FAIL/ERROR (or exactly the expected failures), 1 FAIL/ERROR, 2 usage error or unreachable target.",
    )
    add_run_arguments(run)
    run.set_defaults(func=main_run)

    for name, (text, milestone) in PLANNED.items():
        p = sub.add_parser(name, help=f"{text} [not yet implemented: arrives with {milestone}]")
        p.set_defaults(func=_planned(name, milestone))
    _add_fuzz_and_replay(sub)
    clauses_cli.add_parser(sub)
    wireshark_cli.add_parser(sub)
    diff_cli.add_parser(sub)
    analyze_cli.add_parser(sub)
    monitor_cli.add_parser(sub)
    return parser


def _add_serve(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    from .protocol.answers import SENDABLE_RESULTS

    p = sub.add_parser(
        "serve",
        help="run the reference AI Box (TCP and UDP on one port) until SIGINT/SIGTERM",
        description="Run the reference AI Box. The first line on stdout is "
        "'listening tcp HOST:PORT udp HOST:PORT' (useful with --port 0).",
    )
    net = p.add_argument_group("network")
    net.add_argument("--host", default="127.0.0.1", help="address to listen on (default: 127.0.0.1)")
    net.add_argument("--port", type=int, default=9004, help="TCP (and UDP) port; 0 picks a free one (default: 9004)")
    net.add_argument("--udp-port", type=int, default=None, metavar="PORT",
                     help="UDP port, if not the TCP port (0 picks a free one)")
    net.add_argument("--no-udp", action="store_true", help="serve TCP only")
    net.add_argument("--max-connections", type=int, default=2000, metavar="N",
                     help="[R5] at most N TCP connections; past it the stalest is evicted (default: 2000)")
    net.add_argument("--idle-timeout", type=float, default=300.0, metavar="S",
                     help="[R5] close a connection silent for S seconds; 0 = never (default: 300)")
    net.add_argument("--loop", choices=("asyncio", "uvloop"), default="asyncio",
                     help="event loop (uvloop only if installed; default: asyncio)")
    net.add_argument("--log", metavar="FILE", help="append every frame in and out to FILE as JSON lines")
    knobs = p.add_argument_group("box behaviour")
    knobs.add_argument("--not-ready", action="store_true", help="[S2] answer CycleOn with 0001")
    knobs.add_argument("--cycle-off-fails", action="store_true", help="[A3] answer CycleOff with 0002")
    knobs.add_argument("--latency-ms", type=float, default=0.0, metavar="MS",
                       help="[T1] delay every answer by MS milliseconds (default: 0)")
    knobs.add_argument("--vision-result", type=int, default=1, choices=SENDABLE_RESULTS, metavar="CODE",
                       help="[E3] ResultCode answered to a result request: 1, 2, 10, 20, 202, 400 or 409 (default: 1)")
    knobs.add_argument("--progidx-conflict-box", action="store_true", help="[E2] answer ProgIdx with 409")
    knobs.add_argument("--no-extension", action="store_true",
                       help="[E] do not implement actions 26/27 (treated as unknown actions: silence)")
    knobs.add_argument("--close-on-garbage", action="store_true",
                       help="[A5] close a connection that sends bytes that are not a request (default: stay silent)")
    group = p.add_argument_group("profile")
    add_profile_options(group.add_argument)
    p.set_defaults(func=_serve)


def _serve(args: argparse.Namespace) -> int:
    from .endpoints.behaviour import BoxConfig
    from .endpoints.serve import main_serve

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
        return 1


def _add_robot(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    p = sub.add_parser(
        "robot",
        help="play the canonical robot session (S1, or E4 with --extension) against a box",
        description="Play the canonical robot session against a box and print a timeline and a summary. "
        "Exit status: 0 clean session, 1 the box broke the protocol, 3 box not ready (CycleOn 0001 / ProgIdx 409), "
        "4 no answer within time_out, 5 connection refused or closed, 2 bad arguments.",
    )
    p.add_argument("--target", required=True, metavar="HOST:PORT", help="the box's command connection address")
    p.add_argument("--stream-target", metavar="HOST:PORT", help="the stream connection's address (default: --target)")
    p.add_argument("--duration", type=float, default=2.0, metavar="S",
                   help="seconds of primer trajectory between CycleOn and CycleOff (default: 2)")
    p.add_argument("--extension", action="store_true",
                   help="[E4] play the revision's session: ProgIdx first, result request at the end")
    p.add_argument("--program-index", type=int, default=1, metavar="N", help="[E2] program index to send (default: 1)")
    p.add_argument("--result-wait", type=float, default=1.0, metavar="S",
                   help="[E4] wait between Send_Pos_Off and the result request (default: 1)")
    p.add_argument("--ping", action="store_true", help="send action 00 after connecting (the optional ping)")
    p.add_argument("--loop", choices=("asyncio", "uvloop"), default="asyncio", help="event loop (default: asyncio)")
    p.add_argument("-q", "--quiet", action="store_true", help="print the summary only, not the timeline")
    group = p.add_argument_group("profile")
    add_profile_options(group.add_argument)
    p.set_defaults(func=_robot)


def _robot(args: argparse.Namespace) -> int:
    from .endpoints.loop import new_event_loop
    from .endpoints.robot import RobotSession, run_robot

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


def _add_certify_robot(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    from .certify.cli import add_arguments, main_certify

    p = sub.add_parser(
        "certify-robot",
        help="act as the AI Box and certify a robot (client) implementation against PROTOCOL.md",
        description="Become the AI Box: answer the robot with the reference box's logic, record everything and "
        "judge the robot's frames, session order, stream rate and closes. The first line on stdout is "
        "'listening tcp HOST:PORT udp HOST:PORT'. Exit status: 0 no FAIL/ERROR, 1 FAIL/ERROR, 2 usage error or "
        "no robot connected within --wait. See docs/CERTIFY.md.",
    )
    add_arguments(p)
    p.set_defaults(func=main_certify)


def _add_fuzz_and_replay(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    from .fuzz.cli import add_fuzz_arguments, add_replay_arguments, main_fuzz, main_replay

    fuzz = sub.add_parser(
        "fuzz",
        help="fuzz an AI Box with hypothesis campaigns (valid and malformed frames, and a session state machine)",
        description="Fuzz a box (or, with no --target, the bundled reference box): malformed and valid frames, each "
        "followed by a valid probe and judged by PROTOCOL.md (never 0000 to malformed input, A3's errors, answers in "
        "order, liveness on fresh connections), then a session state machine. Failures are shrunk and written as "
        "vector files (replay them with 'replay') and pcaps. Exit status: 0 no failure, 1 a failure found, 2 usage "
        "error or unreachable target. See docs/FUZZING.md.",
    )
    add_fuzz_arguments(fuzz)
    fuzz.set_defaults(func=main_fuzz)
    replay = sub.add_parser(
        "replay",
        help="resend the vectors of isight-vectors-1 files to a box and show what it does now",
        description="Resend each robot-to-box vector (TCP, or UDP with --udp-target) and show what the box does now "
        "and whether that satisfies PROTOCOL.md. Exit status: 0 all OK now, 1 a vector still fails, 2 usage error "
        "or unreachable target.",
    )
    add_replay_arguments(replay)
    replay.set_defaults(func=main_replay)


def _planned(name: str, milestone: str):  # type: ignore[no-untyped-def]
    def run(args: argparse.Namespace) -> int:
        print(f"isight-conformance {name}: not yet implemented (arrives with {milestone})", file=sys.stderr)
        return 2

    return run


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args, unknown = parser.parse_known_args(argv)
    if unknown and args.command not in PLANNED:
        parser.error(f"unrecognized arguments: {' '.join(unknown)}")
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    try:
        return int(args.func(args))
    except ValueError as exc:  # a bad profile combination and the like
        print(f"isight-conformance {args.command}: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:  # `isight-conformance run --list | head`: the reader left; stay quiet
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        return 0


if __name__ == "__main__":
    sys.exit(main())

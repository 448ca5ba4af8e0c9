"""The ``isight-conformance`` command.

Subcommands that a later milestone fills in say so in ``--help`` and exit with
status 2 and one clear line; they never pretend to have run.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence

from . import __version__
from .options import add_profile_options, profile_from_options
from .protocol import (
    ProtocolError,
    TransferType,
    Transport,
    parse_frame,
)

#: subcommand -> (help, the issue that delivers it)
PLANNED = {
    "run": ("test an AI Box against PROTOCOL.md (conformance suite)", "the suite milestone"),
    "serve": ("run the reference AI Box", "the reference-endpoints milestone"),
    "robot": ("play the canonical robot session against a box", "the reference-endpoints milestone"),
    "fuzz": ("fuzz an AI Box with hypothesis campaigns", "the fuzzing milestone"),
    "replay": ("resend a vector file to a box and show what it does", "the fuzzing milestone"),
    "certify-robot": ("act as a box and certify a robot implementation", "the client-role milestone"),
}


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

    for name, (text, milestone) in PLANNED.items():
        p = sub.add_parser(name, help=f"{text} [not yet implemented: arrives with {milestone}]")
        p.set_defaults(func=_planned(name, milestone))
    return parser


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


if __name__ == "__main__":
    sys.exit(main())

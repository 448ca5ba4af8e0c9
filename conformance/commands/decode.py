"""``isight-conformance decode HEX``: decode one frame and name the clause it breaks."""

from __future__ import annotations

import argparse
import sys

from ..i18n import N_, _
from ..model.exit_codes import EXIT_FAILED, EXIT_OK, EXIT_USAGE
from ..protocol import ProtocolError, TransferType, Transport, parse_frame
from ..runtime.profile_options import profile_from_options
from .options import add_profile_group
from .registry import Command


def add_arguments(dec: argparse.ArgumentParser) -> None:
    dec.add_argument("hex", help=_("the frame's bytes as hex, e.g. fefe000101000000000000000000"))
    dec.add_argument("--udp", action="store_true", help=_("the frame is a UDP datagram (check the CRC)"))
    dec.add_argument("--direction", choices=("robot-to-box", "box-to-robot", "any"), default="any")
    add_profile_group(dec)


def main_decode(args: argparse.Namespace) -> int:
    try:
        data = bytes.fromhex(args.hex.replace(":", "").replace(" ", ""))
    except ValueError:
        print(f"isight-conformance decode: not hex: {args.hex!r}", file=sys.stderr)
        return EXIT_USAGE
    profile = profile_from_options(args)
    expect = {"robot-to-box": TransferType.ROBOT_TO_BOX, "box-to-robot": TransferType.BOX_TO_ROBOT}.get(args.direction)
    transport = Transport.UDP if args.udp else Transport.TCP
    try:
        frame = parse_frame(data, profile, transport, expect)
    except ProtocolError as exc:
        print(f"invalid: {exc}")
        return EXIT_FAILED
    print(f"valid: {frame.describe()}")
    for block in frame.blocks:
        print(f"  {block}")
    return EXIT_OK


COMMAND = Command("decode", N_("decode one frame given as hex and name the clause it breaks"), add_arguments, main_decode)

"""``isight-conformance decode HEX``: decode one frame and name the clause it breaks."""

from __future__ import annotations

import argparse
import sys
from typing import TYPE_CHECKING

from .i18n import _
from .options import add_profile_options, profile_from_options
from .protocol import ProtocolError, TransferType, Transport, parse_frame

if TYPE_CHECKING:
    from .options import Subparsers


def add_parser(sub: Subparsers) -> argparse.ArgumentParser:
    dec = sub.add_parser("decode", help=_("decode one frame given as hex and name the clause it breaks"))
    dec.add_argument("hex", help=_("the frame's bytes as hex, e.g. fefe000101000000000000000000"))
    dec.add_argument("--udp", action="store_true", help=_("the frame is a UDP datagram (check the CRC)"))
    dec.add_argument("--direction", choices=("robot-to-box", "box-to-robot", "any"), default="any")
    group = dec.add_argument_group("profile")
    add_profile_options(group.add_argument)
    dec.set_defaults(func=main_decode)
    return dec


def main_decode(args: argparse.Namespace) -> int:
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

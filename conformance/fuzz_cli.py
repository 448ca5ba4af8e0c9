"""The ``fuzz`` and ``replay`` commands' parsers: what ``--help`` says of them; their options and
handlers are the fuzzer's (:mod:`conformance.fuzz.cli`)."""

from __future__ import annotations

import argparse
from typing import TYPE_CHECKING

from .fuzz.cli import add_fuzz_arguments, add_replay_arguments, main_fuzz, main_replay
from .i18n import _

if TYPE_CHECKING:
    from .options import Subparsers


def add_parser(sub: Subparsers) -> argparse.ArgumentParser:
    fuzz = sub.add_parser(
        "fuzz",
        help=_("fuzz an AI Box with hypothesis campaigns (valid and malformed frames, and a session state machine)"),
        description=_("Fuzz a box (or, with no --target, the bundled reference box): malformed and valid frames, each "
        "followed by a valid probe and judged by PROTOCOL.md (never 0000 to malformed input, A3's errors, answers in "
        "order, liveness on fresh connections), then a session state machine. Failures are shrunk and written as "
        "vector files (replay them with 'replay') and pcaps. Exit status: 0 no failure, 1 a failure found, 2 usage "
        "error or unreachable target. See docs/FUZZING.md."),
    )
    add_fuzz_arguments(fuzz)
    fuzz.set_defaults(func=main_fuzz)
    return fuzz


def add_replay_parser(sub: Subparsers) -> argparse.ArgumentParser:
    replay = sub.add_parser(
        "replay",
        help=_("resend the vectors of isight-vectors-1 files to a box and show what it does now"),
        description=_("Resend each robot-to-box vector (TCP, or UDP with --udp-target) and show what the box does now "
        "and whether that satisfies PROTOCOL.md. Exit status: 0 all OK now, 1 a vector still fails, 2 usage error "
        "or unreachable target."),
    )
    add_replay_arguments(replay)
    replay.set_defaults(func=main_replay)
    return replay

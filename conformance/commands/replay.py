"""The ``replay`` command: its help, its options and its handler (the replay is :mod:`conformance.fuzz.launch`)."""

from __future__ import annotations

import argparse

from ..fuzz.launch import main_replay
from ..i18n import N_, _
from .options import add_profile_group, add_target_options
from .registry import Command


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("files", nargs="+", metavar="FILE", help=_("isight-vectors-1 files (golden vectors or fuzz failures)"))
    add_target_options(p)
    p.add_argument("--tc", type=int, action="append", metavar="ID", help=_("only this tcId (repeatable)"))
    p.add_argument("--one-connection", action="store_true",
                   help=_("send every vector on one connection, in file order (a fuzz 'context' failure)"))
    p.add_argument("--settle-ms", type=int, default=0, metavar="MS",
                   help=_("after each probe's answer, watch this long for late extra answers (default: 0)"))
    add_profile_group(p, _("profile"))


COMMAND = Command(
    "replay", N_("resend the vectors of isight-vectors-1 files to a box and show what it does now"), add_arguments,
    main_replay,
    description=N_("Resend each robot-to-box vector (TCP, or UDP with --udp-target) and show what the box does now "
        "and whether that satisfies PROTOCOL.md. Exit status: 0 all OK now, 1 a vector still fails, 2 usage error "
        "or unreachable target."),
)

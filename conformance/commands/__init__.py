"""The ``isight-conformance`` command: one module per subcommand, one registry.

Every command module defines ``COMMAND``, a :class:`~.registry.Command` (name, help, the
function that adds its arguments, its handler, whether it takes ``--lang``). :data:`COMMANDS`
lists them in ``--help`` order; :func:`main` runs the one chosen: a handler returns the exit
status (:mod:`conformance.model.exit_codes`); a ValueError it lets out is a usage error (2).
"""

from __future__ import annotations

import argparse
import os
import sys
from collections.abc import Sequence

from .. import __version__, i18n
from ..i18n import _
from ..model.exit_codes import EXIT_INTERRUPTED, EXIT_OK, EXIT_USAGE
from . import (
    analyze,
    certify_robot,
    clauses,
    decode,
    diff,
    fuzz,
    monitor,
    replay,
    robot,
    run,
    serve,
    wireshark,
)
from .registry import Command

__all__ = ["COMMANDS", "Command", "build_parser", "main"]

#: every subcommand, in the order ``--help`` lists them (a new command: its module, and one line here)
COMMANDS: tuple[Command, ...] = (
    decode.COMMAND,
    serve.COMMAND,
    robot.COMMAND,
    certify_robot.COMMAND,
    run.COMMAND,
    fuzz.COMMAND,
    replay.COMMAND,
    clauses.COMMAND,
    wireshark.COMMAND,
    diff.COMMAND,
    analyze.COMMAND,
    monitor.COMMAND,
)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="isight-conformance",
        description=_("Conformance and fuzz test suite for the iSight socket protocol (FANUC robot <-> AI Box)."),
    )
    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for command in COMMANDS:
        command_parser = command.add_to(sub)
        # a command that added --lang itself keeps it
        if command.lang and not any(action.dest == "lang" for action in command_parser._actions):
            i18n.add_lang_option(command_parser)
    for each in [parser, *sub.choices.values()]:
        each.formatter_class = i18n.HelpFormatter  # help wrapped by terminal columns (Chinese: two each)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """The command; the language (``--lang``, else the locale) is active while it runs."""
    argv = sys.argv[1:] if argv is None else list(argv)
    try:
        lang = i18n.normalise(i18n.lang_in_argv(argv))
    except ValueError:
        lang = None  # the parser names the bad value
    with i18n.language(lang):
        return _main(argv)


def _main(argv: Sequence[str]) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return EXIT_USAGE
    try:
        return int(args.func(args))
    except ValueError as exc:  # a bad profile combination and the like
        print(f"isight-conformance {args.command}: {exc}", file=sys.stderr)
        return EXIT_USAGE
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    except BrokenPipeError:  # `isight-conformance run --list | head`: the reader left; stay quiet
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        return EXIT_OK


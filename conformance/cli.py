"""The ``isight-conformance`` command: the subcommands, each registered by its own module.

Every command module owns its parser and handler: ``add_parser(sub)`` adds the subcommand
to ``sub`` (what ``add_subparsers()`` returns), sets ``func`` to the handler and returns the
subcommand's parser. This module only lists them, in ``--help`` order, and runs the one
chosen: a handler returns the exit status; a ValueError it lets out is a usage error (2).
"""

from __future__ import annotations

import argparse
import os
import sys
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING

from . import __version__, clauses_cli, decode_cli, fuzz_cli, i18n, run_cli, wireshark_cli
from .analyze import cli as analyze_cli
from .certify import cli as certify_cli
from .endpoints import robot_cli
from .endpoints import serve as serve_cli
from .i18n import _
from .monitor import cli as monitor_cli
from .report import diff_cli

if TYPE_CHECKING:
    from .options import Subparsers

#: every subcommand's ``add_parser``, in the order ``--help`` lists them
COMMANDS: tuple[Callable[[Subparsers], argparse.ArgumentParser], ...] = (
    decode_cli.add_parser,
    serve_cli.add_parser,
    robot_cli.add_parser,
    certify_cli.add_parser,
    run_cli.add_parser,
    fuzz_cli.add_parser,
    fuzz_cli.add_replay_parser,
    clauses_cli.add_parser,
    wireshark_cli.add_parser,
    diff_cli.add_parser,
    analyze_cli.add_parser,
    monitor_cli.add_parser,
)
#: the commands whose output people read take --lang (i18n.add_lang_option; a new command: add its name here)
LANG_COMMANDS = ("run", "certify-robot", "analyze", "fuzz", "diff", "clauses", "monitor")


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="isight-conformance",
        description=_("Conformance and fuzz test suite for the iSight socket protocol (FANUC robot <-> AI Box)."),
    )
    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for add_parser in COMMANDS:
        add_parser(sub)
    for command in [parser, *sub.choices.values()]:
        command.formatter_class = i18n.HelpFormatter  # help wrapped by terminal columns (Chinese: two each)
    for name in LANG_COMMANDS:  # a command that added --lang itself keeps it
        if not any(action.dest == "lang" for action in sub.choices[name]._actions):
            i18n.add_lang_option(sub.choices[name])
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

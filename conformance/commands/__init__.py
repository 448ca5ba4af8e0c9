"""The ``isight-conformance`` command: one module per subcommand, one registry.

Every command module defines ``COMMAND``, a :class:`~.registry.Command` (name, help, the
function that adds its arguments, its handler, whether it takes ``--lang``). :data:`NAMES`
lists them in ``--help`` order; :func:`main` runs the one chosen: a handler returns the exit
status (:mod:`conformance.model.exit_codes`); a ValueError it lets out is a usage error (2).

A command's module is imported only when that command runs (or ``--help`` lists them all):
``isight-conformance decode`` does not pay for the imports of ``analyze`` or ``run``, and
neither does each of the test suite's hundreds of command lines.
"""

from __future__ import annotations

import argparse
import importlib
import os
import sys
from collections.abc import Sequence

from .. import __version__, i18n
from ..i18n import _
from ..model.exit_codes import EXIT_INTERRUPTED, EXIT_OK, EXIT_USAGE
from .registry import Command

__all__ = ["COMMANDS", "NAMES", "Command", "build_parser", "command", "main"]

#: every subcommand's name, in the order ``--help`` lists them (a new command: its module
#: ``commands/<name with _ for ->.py``, and its name here)
NAMES: tuple[str, ...] = ("decode", "serve", "robot", "certify-robot", "run", "fuzz", "replay", "clauses",
                          "wireshark", "diff", "analyze", "monitor", "verify", "sign", "soak")


def command(name: str) -> Command:
    """The command called ``name``: its module is imported now."""
    if name not in NAMES:
        raise KeyError(name)
    module = importlib.import_module(f"{__name__}.{name.replace('-', '_')}")
    found: Command = module.COMMAND
    return found


def __getattr__(attr: str) -> tuple[Command, ...]:
    """``COMMANDS``: every command, every module imported (``--help``, the tests)."""
    if attr == "COMMANDS":
        return tuple(command(name) for name in NAMES)
    raise AttributeError(attr)


def build_parser(only: str | None = None) -> argparse.ArgumentParser:
    """The parser of every command, or with ``only``, of that one (the others are named, bare)."""
    parser = argparse.ArgumentParser(
        prog="isight-conformance",
        description=_("Conformance and fuzz test suite for the iSight socket protocol (FANUC robot <-> AI Box)."),
    )
    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name in NAMES:
        if only is not None and name != only:
            sub.add_parser(name)
            continue
        chosen = command(name)
        command_parser = chosen.add_to(sub)
        # a command that added --lang itself keeps it
        if chosen.lang and not any(action.dest == "lang" for action in command_parser._actions):
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


def _chosen(argv: Sequence[str]) -> str | None:
    """The command named on the line, if any (its first word that is not an option)."""
    first = next((word for word in argv if not word.startswith("-")), None)
    return first if first in NAMES else None


def _main(argv: Sequence[str]) -> int:
    parser = build_parser(_chosen(argv))
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


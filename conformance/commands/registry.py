"""What a subcommand is: a :class:`Command`, one per module of :mod:`conformance.commands`.

A new command is a module here defining ``COMMAND = Command(...)`` and one line in
:data:`conformance.commands.NAMES` (the registry, in ``--help`` order).
"""

from __future__ import annotations

import argparse
from collections.abc import Callable
from dataclasses import dataclass

from ..i18n import gettext


@dataclass(frozen=True)
class Command:
    """One subcommand: its name, its one-line help and longer description (marked with ``N_``,
    translated when the parser is built, so ``--lang`` applies), the function that adds its
    arguments, and the handler that runs it and returns the exit status
    (:mod:`conformance.model.exit_codes`)."""

    name: str
    help: str
    add_arguments: Callable[[argparse.ArgumentParser], None]
    handler: Callable[[argparse.Namespace], int]
    description: str = ""
    #: the command's output is read by people: it takes ``--lang`` (i18n.add_lang_option)
    lang: bool = False

    def add_to(self, sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> argparse.ArgumentParser:
        """Add this command to ``sub`` (what ``add_subparsers()`` returns) and return its parser."""
        parser = sub.add_parser(self.name, help=gettext(self.help),
                                description=gettext(self.description) if self.description else None)
        self.add_arguments(parser)
        parser.set_defaults(func=self.handler)
        return parser

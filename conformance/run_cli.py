"""The ``run`` command's parser: what ``--help`` says of it; its options and its handler are the
runner's (:func:`~conformance.runner.add_run_arguments`, :func:`~conformance.runner.main_run`)."""

from __future__ import annotations

import argparse
from typing import TYPE_CHECKING

from .i18n import _
from .runner import add_run_arguments, main_run

if TYPE_CHECKING:
    from .options import Subparsers


def add_parser(sub: Subparsers) -> argparse.ArgumentParser:
    run = sub.add_parser(
        "run",
        help=_("test an AI Box against PROTOCOL.md and write summary.json, junit.xml, report.html and pcaps"),
        description=_("Run the conformance suite against a box (or, with no --target, the bundled reference box). "
        "Exit status: 0 no FAIL/ERROR (or exactly the expected failures), 1 FAIL/ERROR, 2 usage error or unreachable target."),
    )
    add_run_arguments(run)
    run.set_defaults(func=main_run)
    return run

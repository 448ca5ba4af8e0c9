"""``isight-conformance diff OLD NEW``.

``diff`` compares two runs (each a summary.json or the report directory holding one).
Exit status: 0 nothing got worse, 1 something did (a new FAIL, ERROR or NON-STRICT),
2 a path that is missing, unreadable or not a summary.json (one line on stderr).

``run --baseline OLD`` compares in the report writers (:mod:`conformance.report.run_comparison`).
"""

from __future__ import annotations

import argparse
import os
import sys

from ..i18n import N_, _
from ..model.exit_codes import EXIT_SAME, EXIT_USAGE, EXIT_WORSE
from ..report.diff import compare, render
from ..report.load import SummaryError, load_summary
from .registry import Command


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("old", metavar="OLD", help=_("the earlier run: summary.json or its report directory"))
    p.add_argument("new", metavar="NEW", help=_("the later run: summary.json or its report directory"))
    p.add_argument("--format", choices=("text", "json", "markdown"), default="text",
                   help=_("text (default), json, or markdown (for a CI comment)"))
    p.add_argument("-o", "--output", metavar="FILE", help=_("write the comparison to FILE as well as to stdout"))


def main_diff(args: argparse.Namespace) -> int:
    try:
        old, new = load_summary(args.old), load_summary(args.new)
    except SummaryError as exc:
        print(f"isight-conformance diff: {exc}", file=sys.stderr)
        return EXIT_USAGE
    diff = compare(old, new, os.fspath(args.old), os.fspath(args.new))
    text = render(diff, args.format)
    if args.output:
        from ..report.summary import atomic_write_bytes

        try:
            atomic_write_bytes(args.output, text.encode("utf-8", "backslashreplace"))
        except OSError as exc:
            print(f"isight-conformance diff: cannot write {args.output}: {exc.strerror or exc}", file=sys.stderr)
            return EXIT_USAGE
    sys.stdout.write(text)
    return EXIT_WORSE if diff.got_worse else EXIT_SAME


COMMAND = Command(
    "diff", N_("compare two runs (summary.json files or report directories): what got worse, what got better"), add_arguments, main_diff,
    description=N_("Compare two runs of the suite, e.g. before and after a firmware upgrade. OLD and NEW are "
        "summary.json files or the report directories holding them. Lists what got worse (a new FAIL, ERROR or "
        "NON-STRICT), what got better, other verdict changes, cases added or removed, with each case's clauses. "
        "Exit status: 0 nothing got worse, 1 something did, 2 a path that is missing or not a summary.json."), lang=True,
)

"""The ``run`` command: its help, its options and its handler (the suite's run is
:mod:`.run_flow`; ``run --targets FILE``, a fleet run, is :mod:`.fleet`).

Exit status: 0 nothing FAILed or ERRORed (or the failing set equals the expected-failures
list), 1 something did, 2 usage error or unreachable target, 3 the run was cut short
(:mod:`conformance.model.exit_codes`).
"""

from __future__ import annotations

import argparse
import importlib.util
import sys
from dataclasses import replace
from pathlib import Path

from ..acceptance.declaration import declared_profile
from ..acceptance.record import add_acceptance_options, from_args
from ..endpoints.bundled import bundled_or_target
from ..engine.lanes import AUTO_LANES
from ..harness.concurrency import probe_lanes
from ..harness.target import check_reachable
from ..i18n import N_, _
from ..model.exit_codes import EXIT_USAGE
from ..report.run_comparison import load_baseline
from ..report.rundirs import default_run_dirs
from ..runtime.settings import SuiteSettings, add_suite_options
from .fleet import main_fleet
from .registry import Command
from .run_flow import list_cases, read_expected_failures, run_suite


def add_arguments(parser: argparse.ArgumentParser) -> None:
    group = parser.add_argument_group("suite")
    add_suite_options(group.add_argument)
    group.add_argument("--list", action="store_true", help=_("list the cases (ID, clauses, level, title) and exit"))
    group.add_argument("--list-format", choices=["text", "markdown", "json"], default="text",
                       help=_("with --list: plain text, the Markdown catalogue (docs/CATALOGUE.md), or JSON"))
    group.add_argument("--expected-failures", metavar="FILE", default=None,
                       help=_("case IDs expected to FAIL/ERROR, one per line, # comments; the run passes "
                            "only when the failing set equals the list"))
    group.add_argument("--quiet", action="store_true",
                       help=_("no live progress line: only the final summary, as without a terminal (CI logs)"))
    group.add_argument("--verbose", action="store_true",
                       help=_("print every case as it finishes, PASS, INFORMATIONAL and SKIP included (by default "
                            "a terminal shows only FAIL, ERROR, NON-STRICT and INCONCLUSIVE cases as they finish, "
                            "a log none, before the final summary)"))
    group.add_argument("--baseline", metavar="OLD", default=None,
                       help=_("an earlier run (summary.json or its report directory): print what changed since it "
                            "at the end and add the comparison to report.html (see 'diff')"))
    group.add_argument("--lanes", default="auto", metavar="N|auto",
                       help=_("run the cases that share the box (malformed and parse cases, each on its own "
                            "connections) side by side on N workers, the rest one at a time after them; auto "
                            "(default): 3 when the box is slow to answer (20 ms or more) and serves two connections "
                            "at once, else 1"))
    acceptance = parser.add_argument_group("acceptance (one package per run: see docs/REPORTS.md)")
    add_acceptance_options(acceptance.add_argument)
    fleet = parser.add_argument_group("fleet (several boxes, one run process each; see docs/SCALE.md)")
    fleet.add_argument("--targets", metavar="FILE", default=None,
                       help=_("test every box of this TOML fleet file ([[box]] tables); writes fleet.json and fleet.html "
                            "into --report-dir (default reports/fleet-<timestamp>), each box's reports in DIR/<name>/"))
    fleet.add_argument("--jobs", type=int, metavar="N", default=None, help=_("with --targets: boxes tested at once (default 1)"))


def main_run(args: argparse.Namespace) -> int:
    if getattr(args, "targets", None):
        return main_fleet(args)
    try:
        settings = SuiteSettings.resolve(lambda dest: getattr(args, dest, None))
        expected = read_expected_failures(Path(args.expected_failures)) if args.expected_failures else None
        parse_lanes(getattr(args, "lanes", "1"))  # a bad --lanes is a usage error before anything starts
        baseline = load_baseline(getattr(args, "baseline", None))  # a bad baseline stops the run before it starts
        acceptance = from_args(args)  # a bad --dut or --declared too
        if acceptance.declaration is not None:  # judged under the declared profile
            settings = replace(settings, profile=declared_profile(settings.profile, acceptance.declaration))
    except (ValueError, OSError) as exc:
        print(f"isight-conformance run: {exc}", file=sys.stderr)
        return EXIT_USAGE
    if args.list:
        return list_cases(settings, args.list_format)

    if settings.target is not None:  # before any directory is made: an unreachable target leaves nothing behind
        problem = check_reachable(settings.target, settings.time_out_s)
        if problem:
            print(f"isight-conformance run: {problem}", file=sys.stderr)
            return EXIT_USAGE
    try:
        report_dir, pcap_dir = default_run_dirs(settings.report_dir, settings.pcap_dir, settings.capture != "off")
    except OSError as exc:
        print(f"isight-conformance run: cannot create the report directory: {exc}", file=sys.stderr)
        return EXIT_USAGE
    settings = replace(settings, report_dir=report_dir, pcap_dir=pcap_dir)
    with bundled_or_target(settings.target, settings.udp_target, settings.profile) as (target, udp, box):
        if box is not None:
            settings = replace(settings, target=target, udp_target=udp, target_label=settings.target_label or box.label)
        lanes = choose_lanes(getattr(args, "lanes", "1"), settings)
        return run_suite(settings, expected, quiet=args.quiet, baseline=baseline, verbose=args.verbose, lanes=lanes,
                         acceptance=acceptance)


def parse_lanes(text: str) -> int:
    """``--lanes``: 0 for auto, else the number of lanes (ValueError on anything else)."""
    if text == "auto":
        return 0
    if not text.isdigit() or not 1 <= int(text) <= 16:
        raise ValueError(f"--lanes: expected auto or a number from 1 to 16, got {text!r}")
    return int(text)


def choose_lanes(text: str, settings: SuiteSettings) -> int:
    """The lanes to run with: as asked, or (auto) what :func:`probe_lanes` finds; 1 without pytest-xdist."""
    wanted = parse_lanes(text)
    if wanted == 1:
        return 1
    if importlib.util.find_spec("xdist") is None:
        if wanted:
            print("isight-conformance run: --lanes needs pytest-xdist (pip install 'isight-conformance[xdist]'); "
                  "running one case at a time", file=sys.stderr)
        return 1
    why = "as asked"
    if not wanted:
        assert settings.target is not None
        probe = probe_lanes(settings.target, settings.profile, settings.time_out_s)
        wanted, why = probe.lanes(AUTO_LANES), probe.why
    if wanted > 1:
        print(f"isight-conformance run: {wanted} lanes ({why}): the cases that share the box run side by side, "
              "the rest one at a time after them", file=sys.stderr)
    return wanted


COMMAND = Command(
    "run", N_("test an AI Box against PROTOCOL.md and write summary.json, junit.xml, report.html and pcaps"),
    add_arguments, main_run,
    description=N_("Run the conformance suite against a box (or, with no --target, the bundled reference box). "
        "Exit status: 0 no FAIL/ERROR (or exactly the expected failures), 1 FAIL/ERROR, 2 usage error or unreachable target."),
    lang=True,
)

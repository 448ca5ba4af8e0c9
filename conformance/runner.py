"""``isight-conformance run``: the suite as one command.

A thin driver around pytest: it reads the same options the pytest plugin offers,
starts the bundled reference box when no ``--target`` is given, checks that the
target is reachable (one clear line and exit 2 if not), runs ``conformance.cases``
through :func:`pytest.main` with its settings passed as the plugin's flags (so they
are resolved in one place), shows progress, applies the expected-failures list and
sets the exit code: 0 nothing FAILed or ERRORed (or the failing set equals the
expected-failures list), 1 something did, 2 usage error or unreachable target, 3 the
run was cut short (Ctrl-C, SIGTERM, SIGHUP: the reports cover the cases that ran and
say INCOMPLETE).
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from dataclasses import replace
from pathlib import Path
from typing import Any

import pytest

from . import i18n
from .harness.target import check_reachable
from .i18n import _
from .model.verdicts import CaseResult, RootCause, Verdict
from .protocol.clauses import all_clauses, clause_ids
from .protocol.clauses import families as registry_families
from .report.diff_cli import apply_baseline, load_baseline
from .rundirs import default_run_dirs
from .suite.collected import CAUSES, results, suite_info
from .suite.record import CaseRecord, info_of
from .suite.settings import SuiteSettings, add_suite_options

EXIT_OK, EXIT_FAILED, EXIT_USAGE, EXIT_INCOMPLETE = 0, 1, 2, 3


def add_run_arguments(parser: argparse.ArgumentParser) -> None:
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
    fleet = parser.add_argument_group("fleet (several boxes, one run process each; see docs/SCALE.md)")
    fleet.add_argument("--targets", metavar="FILE", default=None,
                       help=_("test every box of this TOML fleet file ([[box]] tables); writes fleet.json and fleet.html "
                            "into --report-dir (default reports/fleet-<timestamp>), each box's reports in DIR/<name>/"))
    fleet.add_argument("--jobs", type=int, metavar="N", default=None, help=_("with --targets: boxes tested at once (default 1)"))


def read_expected_failures(path: Path) -> set[str]:
    ids = set()
    for line in path.read_text(encoding="utf-8").splitlines():
        text = line.split("#", 1)[0].strip()
        if text:
            ids.add(text)
    return ids


class _RunPlugin:
    """Watches the run: the catalogue collected, progress, collection errors."""

    def __init__(self, progress: Any = None) -> None:
        self.progress = progress
        self.config: pytest.Config | None = None
        self.collected: list[CaseRecord] = []
        self.collect_errors: list[str] = []

    def pytest_configure(self, config: pytest.Config) -> None:
        self.config = config

    def pytest_collection_finish(self, session: pytest.Session) -> None:
        self.collected = [info for item in session.items if (info := info_of(item)) is not None]
        if self.progress is not None:
            self.progress.start(len(self.collected))

    def pytest_collectreport(self, report: pytest.CollectReport) -> None:
        if report.failed:
            self.collect_errors.append(f"{report.nodeid}: {report.longreprtext.strip().splitlines()[-1] if report.longreprtext else 'collection failed'}")

    def pytest_runtest_logstart(self, nodeid: str, location: tuple[str, int | None, str]) -> None:
        if self.progress is not None:
            self.progress.case_started(location[2])

    def pytest_runtest_logreport(self, report: pytest.TestReport) -> None:
        if self.progress is None or self.config is None or not hasattr(report, "isight_verdict"):
            return
        done = results(self.config)
        if done:
            self.progress.case_done(done[-1])


def _pytest_args(settings: SuiteSettings, collect_only: bool = False) -> list[str]:
    # -c devnull: the user's own pytest configuration (addopts, plugins) stays out of the run;
    # --assert=plain: verdicts carry their own evidence, pytest need not rewrite the cases' asserts
    args = ["-c", os.devnull, "--rootdir", os.getcwd(), "--pyargs", "conformance.cases",
            "-p", "no:cacheprovider", "-p", "no:terminal", "-p", "no:warnings", "--assert=plain",
            *settings.to_args(), "--isight-lang", i18n.current()]
    if collect_only:
        args.append("--collect-only")
    return args


def collect(settings: SuiteSettings) -> list[CaseRecord] | None:
    """The selected cases' metadata (None if the catalogue fails to load)."""
    plugin = _RunPlugin()
    code = pytest.main(_pytest_args(settings, collect_only=True), plugins=[plugin])
    return None if code not in (0, 5) or plugin.collect_errors else plugin.collected


def catalogue_markdown(cases: list[CaseRecord]) -> str:
    """docs/CATALOGUE.md: one table per clause family, parametrised cases folded into one row."""
    rows: dict[str, tuple[CaseRecord, list[str]]] = {}
    for info in cases:
        base, _, param = info.id.partition("[")
        if base not in rows:
            rows[base] = (info, [])
        if param:
            rows[base][1].append(param.rstrip("]"))
    families = registry_families()
    out = ["# Case catalogue", "",
           "Generated by `isight-conformance run --list --list-format markdown` from the cases themselves; "
           "do not edit by hand. The clauses are those of [PROTOCOL.md](PROTOCOL.md) "
           "(`isight-conformance clauses ID` prints one). Levels: a MUST broken is FAIL, a SHOULD broken "
           "NON-STRICT, a MAY is INFORMATIONAL.",
           "", f"{len(rows)} cases ({len(cases)} with every parameter).", ""]
    by_family: dict[str, list[tuple[str, CaseRecord, list[str]]]] = {}
    for base, (info, params) in rows.items():
        family = base[0] if base.split("-", 1)[0] in clause_ids() else "other"  # "F1-01" is F; "FUZZ-01" other
        by_family.setdefault(family, []).append((base, info, params))
    for family in [*families, "other"]:
        if family not in by_family:
            continue
        out += [f"## {families.get(family, 'Discovery, sequences and other cases')}", ""]
        if family in families:
            out += ["Clauses: " + "; ".join(f"**{c.id}** {c.title} ({'/'.join(c.levels)})" for c in all_clauses().values()
                                           if c.id[0] == family) + ".", ""]
        out += ["| ID | Clauses | Level | Case | Acceptable outcomes |", "|---|---|---|---|---|"]
        for base, info, params in sorted(by_family[family], key=lambda row: row[0]):
            variants = f" ({len(params)} variants: {', '.join(params[:6])}{', …' if len(params) > 6 else ''})" if params else ""
            cell = (info.title + variants).replace("|", "\\|")
            out.append(f"| {base} | {', '.join(info.clauses)} | {info.level.value} | {cell} | "
                       f"{info.expect.replace('|', '/')} |")
        out.append("")
    return "\n".join(out)


def list_cases(settings: SuiteSettings, fmt: str = "text") -> int:
    cases = collect(settings)
    if cases is None:
        print("isight-conformance run: the case catalogue failed to load", file=sys.stderr)
        return EXIT_USAGE
    if fmt == "markdown":
        print(catalogue_markdown(cases))
    elif fmt == "json":
        print(json.dumps([{"id": c.id, "clauses": list(c.clauses), "level": c.level.value, "title": c.title,
                           "expect": c.expect} for c in cases], indent=1))
    else:
        for info in cases:
            print(f"{info.id:<34} {','.join(info.clauses):<14} {info.level.value:<7} {info.title}")
        print(f"{len(cases)} cases")
    return EXIT_OK


def main_run(args: argparse.Namespace) -> int:
    if getattr(args, "targets", None):
        from .fleet import main_fleet

        return main_fleet(args)
    try:
        settings = SuiteSettings.resolve(lambda dest: getattr(args, dest, None))
        expected = read_expected_failures(Path(args.expected_failures)) if args.expected_failures else None
        baseline = load_baseline(getattr(args, "baseline", None))  # a bad baseline stops the run before it starts
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
    embedded = None
    if settings.target is None:
        from .endpoints.bundled import start_bundled

        embedded = start_bundled(settings.profile)
        settings = replace(settings, target=embedded.target, udp_target=settings.udp_target or embedded.udp_target,
                           target_label=settings.target_label or embedded.label)
    try:
        return _run(settings, expected, quiet=args.quiet, baseline=baseline, baseline_label=args.baseline,
                    verbose=args.verbose)
    finally:
        if embedded is not None:
            embedded.stop()


def _run(settings: SuiteSettings, expected: set[str] | None, quiet: bool, baseline: dict[str, Any] | None = None,
         baseline_label: str = "baseline", verbose: bool = False) -> int:
    from rich.console import Console

    from .report.terminal import Progress, print_final_table

    console = Console(stderr=False)
    progress = Progress(console=console, quiet=quiet, verbose=verbose)
    plugin = _RunPlugin(progress)
    try:
        code = pytest.main(_pytest_args(settings), plugins=[plugin])
    except KeyboardInterrupt:  # a signal between pytest's own handlers: the plugin wrote what it could
        code = pytest.ExitCode.INTERRUPTED
    finally:
        progress.stop()
    if plugin.collect_errors:
        for err in plugin.collect_errors:
            print(f"isight-conformance run: {err}", file=sys.stderr)
        return EXIT_USAGE
    assert plugin.config is not None
    cases = results(plugin.config)
    report_dir = settings.report_dir
    assert report_dir is not None
    failing = {c.id for c in cases if c.verdict.failing}
    if expected is not None:
        _write_lines(report_dir / "failing_cases.txt", sorted(failing))
        _write_lines(report_dir / "unexpectedly_passing.txt", sorted(expected - failing))
    interrupted = code == pytest.ExitCode.INTERRUPTED
    info = suite_info(plugin.config, interrupted=interrupted)
    causes: list[RootCause] = plugin.config.stash.get(CAUSES, [])
    reports: dict[str, Any] = {
        "HTML report": report_dir / "report.html",
        "JSON summary": report_dir / "summary.json",
        "JUnit": report_dir / "junit.xml",
    }
    if settings.pcap_dir is not None:
        reports["pcaps"] = settings.pcap_dir
    print_final_table(info, cases, console, reports=reports, root_causes=causes)
    apply_baseline(baseline, report_dir, cases, console, baseline_label)
    if interrupted or not info.complete:
        print(f"isight-conformance run: interrupted after {len(cases)} of {info.cases_total} cases; the reports "
              "cover the cases that ran and say INCOMPLETE", file=sys.stderr)
        return EXIT_INCOMPLETE
    if code in (pytest.ExitCode.USAGE_ERROR, pytest.ExitCode.INTERNAL_ERROR):
        print(f"isight-conformance run: pytest stopped with exit code {int(code)}", file=sys.stderr)
        return EXIT_USAGE
    if expected is not None:
        if failing == expected:
            return EXIT_OK
        print(_expected_mismatch(failing, expected), file=sys.stderr)
        return EXIT_FAILED
    return EXIT_FAILED if failing else EXIT_OK


def _expected_mismatch(failing: set[str], expected: set[str]) -> str:
    parts = []
    if failing - expected:
        parts.append("unexpected failures: " + ", ".join(sorted(failing - expected)))
    if expected - failing:
        parts.append("expected to fail but did not: " + ", ".join(sorted(expected - failing)))
    return "isight-conformance run: the failing set differs from the expected-failures list; " + "; ".join(parts)


def _write_lines(path: Path, lines: list[str]) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text("".join(f"{line}\n" for line in lines), encoding="utf-8")
    os.replace(tmp, path)


def verdict_counts(cases: list[CaseResult]) -> dict[str, int]:
    return {v.value: sum(1 for c in cases if c.verdict is v) for v in Verdict}

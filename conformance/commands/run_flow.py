"""``isight-conformance run``'s body: the suite through pytest (its parser and handler are
:mod:`conformance.commands.run`).

A thin driver around pytest: the handler reads the same options the pytest plugin offers,
starts the bundled reference box when no ``--target`` is given, checks that the
target is reachable (one clear line and exit 2 if not); this module runs ``conformance.cases``
through :func:`pytest.main` with its resolved settings handed over as an object
(:class:`~conformance.runtime.settings.SettingsPlugin`), shows progress, applies the expected-failures list and
sets the exit code: 0 nothing FAILed or ERRORed (or the failing set equals the
expected-failures list), 1 something did, 2 usage error or unreachable target, 3 the
run was cut short (Ctrl-C, SIGTERM, SIGHUP: the reports cover the cases that ran and
say INCOMPLETE).
"""

from __future__ import annotations

import json
import os
import sys
from pathlib import Path
from typing import Any

import pytest

from .. import i18n
from ..acceptance.record import Acceptance, seal_package
from ..engine.collected import ACCEPTANCE, BASELINE, BASELINE_DIFF, CAUSES, RESULTS, results, suite_info
from ..engine.lanes import ALONE, LANE_PLAN
from ..engine.lanes import plan as lane_plan
from ..model.exit_codes import EXIT_FAILED, EXIT_INCOMPLETE, EXIT_OK, EXIT_USAGE
from ..model.verdicts import RootCause
from ..protocol.clauses import all_clauses, clause_ids
from ..protocol.clauses import families as registry_families
from ..report.run_comparison import Baseline, print_comparison
from ..runtime.settings import SettingsPlugin, SuiteSettings
from ..suite.record import CaseRecord, info_of


def read_expected_failures(path: Path) -> set[str]:
    ids = set()
    for line in path.read_text(encoding="utf-8").splitlines():
        text = line.split("#", 1)[0].strip()
        if text:
            ids.add(text)
    return ids


class _RunPlugin:
    """Watches the run: the catalogue collected, progress, collection errors."""

    def __init__(self, progress: Any = None, baseline: Baseline | None = None, lanes: int = 1,
                 plan: dict[str, str] | None = None, acceptance: Acceptance | None = None) -> None:
        self.progress = progress
        self.baseline = baseline
        self.acceptance = acceptance  # the run's package: run ID, DUT, tester, declaration
        self.lanes = lanes  # collecting: plan this many lanes
        self.plan = plan  # running: each case's lane (run under pytest-xdist)
        self.config: pytest.Config | None = None
        self.collected: list[CaseRecord] = []
        self.collect_errors: list[str] = []

    def pytest_configure(self, config: pytest.Config) -> None:
        self.config = config
        config.stash[BASELINE] = self.baseline  # the report writers compare with it (report.html once)
        if self.acceptance is not None:
            config.stash[ACCEPTANCE] = self.acceptance
        if self.plan:
            config.stash[LANE_PLAN] = self.plan
            if self.progress is not None:  # under xdist the controller collects nothing: the plan has the count
                self.progress.start(len(self.plan))

    @pytest.hookimpl(tryfirst=True)
    def pytest_sessionfinish(self, session: pytest.Session, exitstatus: int) -> None:
        """Before the reports are written: the declared / observed table, and a FAIL case per contradicted
        declaration among the results (so the overall line, the exit status and every report count it)."""
        config = session.config
        if self.acceptance is None or hasattr(config, "workerinput"):
            return
        found = config.stash.get(RESULTS, {})
        key = next(iter(found), "")
        if key not in found or not found[key]:
            return
        extension = suite_info(config, key=key).extension
        accepted, contradicted = self.acceptance.judged(found[key], {"extension": extension})
        found[key].extend(contradicted)
        config.stash[ACCEPTANCE] = self.acceptance = accepted

    def pytest_collection_finish(self, session: pytest.Session) -> None:
        self.collected = [info for item in session.items if (info := info_of(item)) is not None]
        if self.lanes > 1:
            self.plan = lane_plan(session.items, self.lanes)
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


def _pytest_args(collect_only: bool = False) -> list[str]:
    # -c devnull: the user's own pytest configuration (addopts, plugins) stays out of the run;
    # --assert=plain: verdicts carry their own evidence, pytest need not rewrite the cases' asserts
    args = ["-c", os.devnull, "--rootdir", os.getcwd(), "--pyargs", "conformance.cases",
            "-p", "no:cacheprovider", "-p", "no:terminal", "-p", "no:warnings", "--assert=plain",
            "--isight-lang", i18n.current()]
    if collect_only:
        args.append("--collect-only")
    return args


def collect(settings: SuiteSettings) -> list[CaseRecord] | None:
    """The selected cases' metadata (None if the catalogue fails to load)."""
    plugin = _RunPlugin()
    code = pytest.main(_pytest_args(collect_only=True), plugins=[plugin, SettingsPlugin(settings)])
    return None if code not in (0, 5) or plugin.collect_errors else plugin.collected


def plan_lanes(settings: SuiteSettings, lanes: int) -> dict[str, str] | None:
    """Each selected case's lane (:mod:`conformance.engine.lanes`); None if no two lanes would have work."""
    plugin = _RunPlugin(lanes=lanes)
    code = pytest.main(_pytest_args(collect_only=True), plugins=[plugin, SettingsPlugin(settings)])
    if code not in (0, 5) or plugin.collect_errors or not plugin.plan:
        return None
    return plugin.plan if len({s for s in plugin.plan.values() if s != ALONE}) > 1 else None


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


def run_suite(settings: SuiteSettings, expected: set[str] | None, quiet: bool, baseline: Baseline | None = None,
              verbose: bool = False, lanes: int = 1, acceptance: Acceptance | None = None) -> int:
    """Run the selected cases against ``settings.target`` (known to answer), show progress and the final
    table, and return the exit status. ``lanes`` > 1: the cases that share the box run side by side on
    that many pytest-xdist workers (:mod:`conformance.engine.lanes`), the rest one at a time after them."""
    from rich.console import Console

    from ..report.terminal import Progress, print_final_table

    console = Console(stderr=False)
    progress = Progress(console=console, quiet=quiet, verbose=verbose)
    plan = plan_lanes(settings, lanes) if lanes > 1 else None
    plugin = _RunPlugin(progress, baseline, plan=plan, acceptance=acceptance)
    try:
        code = pytest.main(_pytest_args() + (["-n", str(lanes)] if plan else []),
                           plugins=[plugin, SettingsPlugin(settings)])
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
    sealed = seal_package(report_dir, plugin.acceptance)  # the package's manifest, written last
    if sealed:
        reports["manifest"] = report_dir / "manifest.json"
        reports["manifest sha256"] = sealed
    print_final_table(info, cases, console, reports=reports, root_causes=causes)
    print_comparison(baseline, plugin.config.stash.get(BASELINE_DIFF, None), console)
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


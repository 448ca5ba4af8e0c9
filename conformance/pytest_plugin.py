"""The pytest plugin (entry point ``pytest11: isight``): thin, like pytest-timeout.

Options live in one group (``isight``) and are resolved once, in ``pytest_configure``,
into :class:`~conformance.runtime.settings.SuiteSettings`; ``isight-conformance run`` hands
its resolved settings over as an object instead (:class:`~conformance.runtime.settings.SettingsPlugin`),
and an xdist worker takes the controller's, serialised once. Every hook forwards:

* the ``isight`` fixture makes the case's :class:`~conformance.suite.case_context.CaseContext`
  (its transcript recorded to a pcap) and asks the session whether the case may run
  (:meth:`~conformance.runtime.run_state.SessionState.before_case`);
* ``pytest_pyfunc_call`` closes the case's connections and hands what it raised to
  :meth:`~conformance.runtime.run_state.SessionState.after_case` (liveness, R2/S5);
* ``pytest_runtest_makereport`` turns it into a CaseResult (:mod:`conformance.engine.results`)
  and shapes pytest's report (verdict words, the evidence section);
* ``pytest_sessionfinish`` finds the root causes and writes the reports, also for a run
  cut short by Ctrl-C, SIGTERM or SIGHUP (marked INCOMPLETE, the cases not run listed).

With ``--target`` given several times every case runs against each box (one session
and one report per box). Under pytest-xdist (:mod:`conformance.xdist_hooks`, registered
only when xdist is present) one box's cases stay on one worker in catalogue order, the
workers send their results to the controller, and only the controller writes reports.

Only items marked with :func:`conformance.suite.record.case` are touched, so the
plugin is inert in any other test session.
"""

from __future__ import annotations

import fnmatch
import json
import time
from collections.abc import Generator
from dataclasses import replace
from pathlib import Path

import pytest

from . import __version__, i18n
from .engine import signals
from .engine.collected import (  # noqa: F401 - CAUSES, results, suite_info, root_causes: the plugin's API too
    ACCEPTANCE,
    BASELINE,
    BASELINE_DIFF,
    CAUSES,
    FACTS,
    RESULTS,
    SELECTED,
    SESSIONS,
    SETTINGS,
    STARTED,
    STATE,
    facts_of,
    results,
    root_causes,
    session_facts,
    suite_info,
    target_keys,
    wants_suite,
)
from .engine.results import attach_evidence, result_of, safe_name
from .harness.transcript import Transcript
from .model.verdicts import CaseResult, RootCause, Verdict
from .runtime.run_state import SessionState
from .runtime.settings import SuiteSettings, add_suite_options, handed_settings
from .suite.case_context import CaseContext
from .suite.record import info_of

CTX = pytest.StashKey[CaseContext]()
CASE_START = pytest.StashKey[float]()


#: the catalogue's package: its modules are named by clause family (``frame.py``, ``blocks.py``...), not ``test_*.py``
CATALOGUE = Path(__file__).resolve().parent / "cases"


def pytest_collect_file(file_path: Path, parent: pytest.Collector) -> pytest.Module | None:
    """Collect the catalogue's modules whatever ``python_files`` says (``--pyargs conformance.cases``).

    A module pytest collects anyway (named on the command line, or matching ``python_files``) is
    left to pytest, so no case is collected twice."""
    if file_path.suffix != ".py" or file_path.name == "__init__.py" or file_path.parent.resolve() != CATALOGUE:
        return None
    if parent.session.isinitpath(file_path) or any(
            fnmatch.fnmatch(file_path.name, pattern) for pattern in parent.config.getini("python_files")):
        return None
    return pytest.Module.from_parent(parent, path=file_path)


def pytest_addoption(parser: pytest.Parser) -> None:
    group = parser.getgroup("isight", "iSight conformance suite")
    add_suite_options(group.addoption, pytest=True)
    i18n.add_lang_option(group.addoption, "--isight-lang", dest="isight_lang")


LANG_BEFORE = pytest.StashKey[str]()


def pytest_configure(config: pytest.Config) -> None:
    config.addinivalue_line("markers", "isight_case(info): an iSight conformance case (set by @case)")
    config.addinivalue_line("markers", "isight_alone: this variant of a case that shares the box runs alone (run's lanes)")
    lang = config.getoption("isight_lang", None)
    if lang or wants_suite(config):  # the project's own tests keep English whatever the locale says
        config.stash[LANG_BEFORE] = i18n.current()  # the reports' language for this session; restored at its end
        i18n.activate(lang)
    # the run's settings: an xdist worker's from its controller, else those handed over as an object
    # (isight-conformance run), else resolved from the flags (pytest --pyargs conformance.cases ...)
    settings = handed_settings(config.pluginmanager.get_plugins(), getattr(config, "workerinput", None))
    if settings is None:
        try:
            settings = SuiteSettings.resolve(lambda dest: config.getoption(dest, None))
        except ValueError as exc:
            raise pytest.UsageError(str(exc)) from None
    config.stash[SETTINGS] = settings
    if config.pluginmanager.hasplugin("xdist"):
        from .xdist_hooks import XdistHooks

        config.pluginmanager.register(XdistHooks(config), "isight-xdist")
    sessions = {key: SessionState(replace(settings, target=t, targets=(t,)) if t is not None else settings)
                for key, t in target_keys(settings).items()}
    config.stash[SESSIONS] = sessions
    config.stash[STATE] = next(iter(sessions.values()))
    empty: dict[str, list[CaseResult]] = {key: [] for key in sessions}
    config.stash[RESULTS] = empty
    config.stash[FACTS] = {}
    config.stash[SELECTED] = []
    config.stash[STARTED] = time.time()
    if wants_suite(config):
        signals.install()  # SIGTERM and SIGHUP end the run like Ctrl-C: the reports are still written


def pytest_unconfigure(config: pytest.Config) -> None:
    signals.restore()
    if LANG_BEFORE in config.stash:
        i18n.activate(config.stash[LANG_BEFORE])
    for state in config.stash.get(SESSIONS, {}).values():
        state.stop()


def pytest_report_header(config: pytest.Config) -> list[str] | None:
    if not wants_suite(config):
        return None
    state = config.stash[STATE]
    s = state.settings
    return [
        f"isight-conformance {__version__}: target {s.target or 'bundled reference box (started on the first case)'}"
        + (f", UDP {s.udp_target}" if s.udp_target else ", no UDP target (UDP cases SKIP)"),
        f"profile: {state.profile.describe()}",
    ]


@pytest.hookimpl(trylast=True)
def pytest_generate_tests(metafunc: pytest.Metafunc) -> None:
    """Several boxes: every case once per box (the box's key is the last part of the item's id)."""
    keys: list[str] = list(metafunc.config.stash[SESSIONS].keys())
    if "isight" in metafunc.fixturenames and len(keys) > 1:
        metafunc.parametrize("isight_target", keys, indirect=True, ids=keys)


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    # profile discovery first: its hints matter most when everything else fails
    items.sort(key=lambda item: 0 if (info := info_of(item)) is not None and "any-profile" in info.needs else 1)
    settings = config.stash[STATE].settings
    if settings.cases or settings.exclude:
        keep: list[pytest.Item] = []
        drop: list[pytest.Item] = []
        for item in items:
            info = info_of(item)
            # the baseline ("always") runs whatever --cases says; only --exclude drops it
            always = info is not None and "always" in info.needs and not any(
                fnmatch.fnmatchcase(info.id, g) for g in settings.exclude)
            (keep if info is None or always or settings.selects(info.id) else drop).append(item)
        if drop:
            config.hook.pytest_deselected(items=drop)
            items[:] = keep
    config.stash[SELECTED] = [info.id for item in items if (info := info_of(item)) is not None]


# -- the fixture and the case run ----------------------------------------------------------------


@pytest.fixture
def isight_target(request: pytest.FixtureRequest) -> str:
    """The key of the box the case runs against ("" when the run has one box)."""
    return str(getattr(request, "param", ""))


@pytest.fixture
def isight(request: pytest.FixtureRequest, isight_target: str) -> Generator[CaseContext, None, None]:
    """The case's context: recorded connections to the target box."""
    item = request.node
    info = info_of(item)
    if info is None:
        raise pytest.UsageError(f"{item.nodeid} uses the isight fixture but is not marked with @case")
    state = item.config.stash[SESSIONS][isight_target]
    item.stash[CASE_START] = time.monotonic()
    transcript = Transcript(case_id=info.id)
    callspec = getattr(item, "callspec", None)
    ctx = CaseContext(state, info, transcript, dict(callspec.params) if callspec is not None else None)
    item.stash[CTX] = ctx
    ctx.pcap = attach_evidence(transcript, state.settings, info.id)
    try:
        state.before_case(info.id, transcript, any_profile="any-profile" in info.needs)
        yield ctx
    finally:
        ctx.close_all()
        transcript.close()


@pytest.hookimpl(wrapper=True)
def pytest_pyfunc_call(pyfuncitem: pytest.Function) -> Generator[None, object, object]:
    ctx = pyfuncitem.stash.get(CTX, None)
    if ctx is None:
        return (yield)
    error: BaseException | None = None
    result: object = None
    try:
        result = yield
    except Exception as exc:  # handed to the session below, then re-raised
        error = exc
    ctx.close_all()  # first: a box that serves one connection at a time is then free for the liveness check
    error = ctx.session.after_case(ctx.info.id, ctx.transcript, malformed_input=ctx.needs_liveness,
                                   last_sent=ctx.last_sent, error=error)
    if error is not None:
        raise error
    return result


@pytest.hookimpl(tryfirst=True, specname="pytest_runtest_makereport")
def pytest_runtest_makereport_of_a_case(item: pytest.Item, call: pytest.CallInfo[None]) -> pytest.TestReport | None:
    """A case's report when it raised (not a skip): built here, with the exception's one line as its
    ``longrepr``, so that pytest does not parse sources for a traceback of every INCONCLUSIVE and FAIL
    (seconds on a dead box's run); the verdict carries the evidence and the wrapper below shapes the
    report from it. Anything else: None, pytest's own report."""
    excinfo, when = call.excinfo, call.when
    if info_of(item) is None or excinfo is None or excinfo.errisinstance(pytest.skip.Exception) or when == "collect":
        return None
    return pytest.TestReport(item.nodeid, item.location, dict.fromkeys(item.keywords, 1), "failed",
                             f"{excinfo.typename}: {excinfo.value}", when, (), call.duration, call.start,
                             call.stop, user_properties=item.user_properties)


@pytest.hookimpl(wrapper=True)
def pytest_runtest_makereport(item: pytest.Item, call: pytest.CallInfo[None]) -> Generator[None, pytest.TestReport, pytest.TestReport]:
    rep = yield
    info = info_of(item)
    if info is None or rep.when == "teardown" or (rep.when == "setup" and rep.passed):
        return rep
    ctx = item.stash.get(CTX, None)
    exc = call.excinfo.value if call.excinfo is not None else None
    skipped = call.excinfo is not None and call.excinfo.errisinstance(pytest.skip.Exception)
    start = item.stash.get(CASE_START, None)
    duration = (time.monotonic() - start) if start is not None else rep.duration
    result = result_of(info, ctx, exc, duration, skipped)
    item.config.stash[RESULTS][_key_of(item)].append(result)
    if hasattr(item.config, "workerinput"):  # an xdist worker: the result travels with its report to the controller
        rep.__dict__["isight_result"] = json.loads(json.dumps(result.to_dict(), default=str))
    _shape_report(rep, item, result)
    return rep


def _shape_report(rep: pytest.TestReport, item: pytest.Item, result: CaseResult) -> None:
    verdict = result.verdict
    rep.__dict__["isight_verdict"] = verdict.value  # an extra attribute, as TestReport(**extra) sets them
    rep.user_properties.extend([("isight_case", result.id), ("isight_verdict", verdict.value)])
    if result.pcap:
        rep.user_properties.append(("pcap", result.pcap))
    evidence = [f"case {result.id} [{', '.join(result.clauses)}] {result.level.value}: {verdict.value}"]
    if result.pcap:
        evidence.append(f"pcap: {result.pcap}")
    evidence += [f"{w.t_ms:10.3f} ms  #{w.conn} {w.direction} {w.kind:<10} {w.summary}  {w.hex[:120]}" for w in result.wire[:200]]
    rep.sections.append(("isight evidence", "\n".join(evidence)))
    if verdict in (Verdict.PASS, Verdict.NON_STRICT, Verdict.INFORMATIONAL):
        rep.outcome = "passed"
        rep.longrepr = None
    elif verdict in (Verdict.SKIP, Verdict.INCONCLUSIVE):
        rep.outcome = "skipped"
        path, lineno, _ = item.location
        rep.longrepr = (str(path), (lineno or 0) + 1, f"{verdict.value}: {result.message}")
    elif verdict is Verdict.FAIL:
        rep.outcome = "failed"
        rep.longrepr = _failure_text(result)


def _failure_text(result: CaseResult) -> str:
    lines = [f"{result.id} [{', '.join(result.clauses)}] {result.level.value} FAIL: {result.message}"]
    for label, value in (("requirement", result.requirement), ("expected", result.expected),
                         ("observed", result.observed), ("sent", result.sent_hex), ("received", result.received_hex),
                         ("pcap", result.pcap)):
        if value:
            lines.append(f"  {label:<11} {value}")
    return "\n".join(lines)


def pytest_report_teststatus(report: pytest.TestReport, config: pytest.Config) -> tuple[str, str, str] | None:
    verdict = getattr(report, "isight_verdict", None)
    if verdict == Verdict.NON_STRICT.value:
        return "non-strict", "N", "NON-STRICT"
    if verdict == Verdict.INFORMATIONAL.value:
        return "informational", "I", "INFORMATIONAL"
    if verdict == Verdict.INCONCLUSIVE.value:
        return "inconclusive", "c", "INCONCLUSIVE"
    return None


def _key_of(item: pytest.Item) -> str:
    callspec = getattr(item, "callspec", None)
    return str(callspec.params.get("isight_target", "")) if callspec is not None else ""


# -- session end ---------------------------------------------------------------------------------


def pytest_sessionfinish(session: pytest.Session, exitstatus: int) -> None:
    config = session.config
    if hasattr(config, "workerinput"):  # an xdist worker: its controller writes the reports
        return
    causes: dict[str, list[RootCause]] = {}
    for key, state in config.stash.get(SESSIONS, {}).items():
        cases = results(config, key)
        if not cases:
            continue
        from .diagnose.phase import run_phase

        causes[key] = run_phase(state, cases, root_causes(config, key), session_facts(config, key))  # <= 20 s
        if state.settings.report_dir is None:
            continue
        from .diagnose.repro import write_repros
        from .report import write_reports

        report_dir = Path(state.settings.report_dir) / (safe_name(key) if key else "")
        with signals.deferred():  # a second signal does not cut the reports short
            info = suite_info(config, interrupted=exitstatus == pytest.ExitCode.INTERRUPTED, key=key)
            accepted = config.stash.get(ACCEPTANCE, None)
            diff = write_reports(report_dir, info, cases, causes[key], baseline=config.stash.get(BASELINE, None),
                                 acceptance=accepted.to_dict() if accepted is not None else None)
            write_repros(report_dir, causes[key], state.profile)
        config.stash.setdefault(BASELINE_DIFF, diff)
    config.stash[CAUSES] = next(iter(causes.values()), [])

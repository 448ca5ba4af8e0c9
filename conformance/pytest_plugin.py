"""The pytest plugin (entry point ``pytest11: isight``): thin, like pytest-timeout.

- options in one group (``isight``), resolved once into :class:`SuiteSettings`;
- ``isight`` fixture: a :class:`CaseContext` per case, its transcript recorded to a pcap;
- a ``pytest_pyfunc_call`` wrapper runs the liveness check after malformed input (R2);
- ``pytest_runtest_makereport`` turns what the case raised into a verdict, attaches
  the evidence (pcap path, wire log, hex) to the report, and keeps the CaseResult;
- reports are written at session end when ``--report-dir`` is given.

Only items marked with :func:`conformance.suite.catalogue.case` are touched, so the
plugin is inert in any other test session.
"""

from __future__ import annotations

import datetime as _dt
import fnmatch
import shlex
import sys
import time
import traceback
from collections.abc import Generator
from pathlib import Path
from typing import Any

import pytest

from . import __version__
from .harness.target import Unreachable
from .harness.transcript import Transcript
from .suite.catalogue import CaseInfo, info_of
from .suite.context import DEAD_RECHECK_S, CaseContext, SessionState, responsive
from .suite.judge import CaseVerdict, Inconclusive
from .suite.settings import SuiteSettings, add_suite_options
from .suite.verdicts import CaseResult, SuiteInfo, Verdict
from .suite.wirelog import wire_lines

STATE = pytest.StashKey[SessionState]()
RESULTS = pytest.StashKey[list[CaseResult]]()
STARTED = pytest.StashKey[float]()
CTX = pytest.StashKey[CaseContext]()
CASE_START = pytest.StashKey[float]()


def pytest_addoption(parser: pytest.Parser) -> None:
    group = parser.getgroup("isight", "iSight conformance suite")
    add_suite_options(group.addoption, pytest=True)


def pytest_configure(config: pytest.Config) -> None:
    config.addinivalue_line("markers", "isight_case(info): an iSight conformance case (set by @case)")
    injected = [p.isight_settings for p in config.pluginmanager.get_plugins()
                if isinstance(getattr(p, "isight_settings", None), SuiteSettings)]
    try:
        settings = injected[0] if injected else SuiteSettings.resolve(lambda dest: config.getoption(dest, None))
    except ValueError as exc:
        raise pytest.UsageError(str(exc)) from None
    config.stash[STATE] = SessionState(settings)
    config.stash[RESULTS] = []
    config.stash[STARTED] = time.time()


def pytest_unconfigure(config: pytest.Config) -> None:
    state = config.stash.get(STATE, None)
    if state is not None:
        state.stop()


def _wants_suite(config: pytest.Config) -> bool:
    return bool(config.getoption("isight_target", None)) or any("conformance.cases" in str(a) for a in config.args)


def pytest_report_header(config: pytest.Config) -> list[str] | None:
    if not _wants_suite(config):
        return None
    state = config.stash[STATE]
    s = state.settings
    return [
        f"isight-conformance {__version__}: target {s.target or 'bundled reference box (started on the first case)'}"
        + (f", UDP {s.udp_target}" if s.udp_target else ", no UDP target (UDP cases SKIP)"),
        f"profile: {state.profile.describe()}",
    ]


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    # profile discovery first: its hints matter most when everything else fails
    items.sort(key=lambda item: 0 if (info := info_of(item)) is not None and "any-profile" in info.needs else 1)
    settings = config.stash[STATE].settings
    if not (settings.cases or settings.exclude):
        return
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


# -- the fixture ---------------------------------------------------------------------------


@pytest.fixture
def isight(request: pytest.FixtureRequest) -> Generator[CaseContext, None, None]:
    """The case's context: recorded connections to the target box."""
    item = request.node
    info = info_of(item)
    if info is None:
        raise pytest.UsageError(f"{item.nodeid} uses the isight fixture but is not marked with @case")
    state = item.config.stash[STATE]
    item.stash[CASE_START] = time.monotonic()
    transcript = Transcript(case_id=info.id)
    ctx = CaseContext(state, info, transcript)
    item.stash[CTX] = ctx
    _attach_evidence(ctx, state.settings)
    _baseline(ctx, state)
    if "any-profile" not in info.needs:
        _refuse_if_dead(ctx, state)
    try:
        yield ctx
    finally:
        ctx.close_all()
        transcript.close()


def _attach_evidence(ctx: CaseContext, settings: SuiteSettings) -> None:
    if settings.pcap_dir is None or settings.capture == "off":
        return
    settings.pcap_dir.mkdir(parents=True, exist_ok=True)
    path = settings.pcap_dir / f"{_safe(ctx.info.id)}.pcapng"
    if settings.capture == "live":
        from .evidence.live import LiveCapture  # needs privileges; says so clearly

        capture = LiveCapture(path=path, case_id=ctx.info.id)
        ctx.transcript.listeners.append(capture)  # type: ignore[arg-type]
        capture.start()
    else:
        from .evidence.pcap import PcapRecorder

        ctx.transcript.listeners.append(PcapRecorder(path, case_id=ctx.info.id))
    ctx.pcap = path


def _safe(case_id: str) -> str:
    return "".join(c if c.isalnum() or c in "-_." else "_" for c in case_id)


def _baseline(ctx: CaseContext, state: SessionState) -> None:
    """Once per session: does the box answer NONE at all, in this profile?"""
    if state.baseline is not None:
        return
    try:
        ctx.target  # noqa: B018 - resolves (and may start) the target
    except Exception as exc:  # the bundled box failed to start: the suite's fault
        raise RuntimeError(f"could not start the bundled reference box: {exc}") from exc
    state.baseline = ctx.check_alive()
    if not responsive(state.baseline):
        state.health.dead_since_case = "session start"
        state.health.reason = (
            f"the box does not answer a NONE request (it {state.baseline.describe()}); "
            "PROFILE-01 tells which profile it appears to use"
        )
        state.health.last_check = time.monotonic()


def _refuse_if_dead(ctx: CaseContext, state: SessionState) -> None:
    health = state.health
    if health.dead_since_case is None:
        return
    now = time.monotonic()
    if now - health.last_check >= DEAD_RECHECK_S:
        health.last_check = now
        outcome = ctx.check_alive()
        if responsive(outcome):
            health.dead_since_case = None
            ctx.transcript.note("the box answers again")
            return
    raise Inconclusive(f"box unreachable since case {health.dead_since_case} ({health.reason})")


# -- liveness after malformed input (R2) ----------------------------------------------------


@pytest.hookimpl(wrapper=True)
def pytest_pyfunc_call(pyfuncitem: pytest.Function) -> Generator[None, object, object]:
    ctx = pyfuncitem.stash.get(CTX, None)
    if ctx is None:
        return (yield)
    error: BaseException | None = None
    result: object = None
    try:
        result = yield
    except BaseException as exc:  # re-raised below, after the liveness check
        error = exc
    if (ctx.needs_liveness or ctx.transcript.timeouts) and not isinstance(error, Inconclusive):
        alive = ctx.check_alive()
        ok = responsive(alive)
        if not ok:
            health = ctx.session.health
            health.dead_since_case = ctx.info.id
            health.reason = f"a fresh connection {alive.describe()}"
            health.last_check = time.monotonic()
        if not ok and ctx.needs_liveness and state_baseline_ok(ctx.session):
            dead = CaseVerdict(
                Verdict.FAIL,
                f"R2: after this case's input the box no longer answers a fresh connection (it {alive.describe()})",
                requirement="R2: whatever bytes one connection sends, the box keeps accepting and answering new connections",
                expected="a fresh connection's NONE request answered",
                observed=alive.describe(),
                sent=ctx.last_sent,
            )
            if not (isinstance(error, CaseVerdict) and error.verdict is Verdict.FAIL):
                error = dead
            else:
                error.message += f" (and then the box stopped answering new connections: {alive.describe()})"
    if error is not None:
        raise error
    return result


def state_baseline_ok(state: SessionState) -> bool:
    return state.baseline is not None and responsive(state.baseline)


# -- verdicts and evidence ------------------------------------------------------------------


def _classify(excinfo: pytest.ExceptionInfo[BaseException] | None, info: CaseInfo, ctx: CaseContext | None) -> tuple[Verdict, dict[str, Any]]:
    if excinfo is None:
        if ctx is not None and ctx.informational is not None:
            return Verdict.INFORMATIONAL, {"message": ctx.informational, "observed": ctx.informational}
        return Verdict.PASS, {"message": ""}
    exc = excinfo.value
    if isinstance(exc, CaseVerdict):
        return exc.verdict, {
            "message": exc.message, "requirement": exc.requirement, "expected": exc.expected,
            "observed": exc.observed, "sent_hex": exc.sent.hex(" "), "received_hex": exc.received.hex(" "),
        }
    if isinstance(exc, Unreachable):
        return Verdict.INCONCLUSIVE, {"message": f"box unreachable: {exc}"}
    if excinfo.errisinstance(pytest.skip.Exception):
        return Verdict.SKIP, {"message": str(getattr(exc, "msg", exc))}
    if isinstance(exc, AssertionError):
        return info.level.broken_verdict, {"message": str(exc).splitlines()[0] if str(exc) else "assertion failed"}
    tb = "".join(traceback.format_exception(type(exc), exc, exc.__traceback__)[-3:])
    return Verdict.ERROR, {"message": f"suite error: {type(exc).__name__}: {exc}", "observed": tb}


@pytest.hookimpl(wrapper=True)
def pytest_runtest_makereport(item: pytest.Item, call: pytest.CallInfo[None]) -> Generator[None, pytest.TestReport, pytest.TestReport]:
    rep = yield
    info = info_of(item)
    if info is None or rep.when == "teardown" or (rep.when == "setup" and rep.passed):
        return rep
    ctx = item.stash.get(CTX, None)
    verdict, fields = _classify(call.excinfo, info, ctx)
    if verdict is not Verdict.PASS:
        # every non-PASS verdict carries the requirement and the bytes (defaults from the case)
        fields["requirement"] = fields.get("requirement") or f"{', '.join(info.clauses)} ({info.level.value}): {info.title}"
        if ctx is not None and not fields.get("sent_hex") and ctx.last_sent:
            fields["sent_hex"] = ctx.last_sent.hex(" ")

    start = item.stash.get(CASE_START, None)
    result = CaseResult(
        id=info.id, title=info.title, clauses=info.clauses, level=info.level, verdict=verdict,
        duration_s=(time.monotonic() - start) if start is not None else rep.duration,
        expected=fields.pop("expected", "") or info.expect,
        pcap=str(ctx.pcap) if ctx is not None and ctx.pcap is not None else None,
        **fields,
    )
    if ctx is not None:
        result.wire = wire_lines(ctx.transcript, ctx.profile)
        result.latencies_ms = list(ctx.latencies_ms)
        result.details = dict(ctx.details)
    item.config.stash[RESULTS].append(result)
    _shape_report(rep, item, result)
    return rep


def _shape_report(rep: pytest.TestReport, item: pytest.Item, result: CaseResult) -> None:
    verdict = result.verdict
    rep.isight_verdict = verdict.value  # type: ignore[attr-defined]
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


# -- session end ---------------------------------------------------------------------------


def suite_info(config: pytest.Config) -> SuiteInfo:
    state = config.stash[STATE]
    started = config.stash[STARTED]
    return SuiteInfo(
        version=__version__,
        started=_dt.datetime.fromtimestamp(started, _dt.timezone.utc).isoformat(timespec="seconds"),
        duration_s=round(time.time() - started, 3),
        target=state.target_label(),
        profile=state.profile.to_dict(),
        udp_target=str(state.udp_target()) if state._target is not None and state.udp_target() else None,
        extension=state.extension_how or ("not checked" if state.settings.extension == "auto" else state.settings.extension),
        command=" ".join(shlex.quote(a) for a in sys.argv),
    )


def results(config: pytest.Config) -> list[CaseResult]:
    found: list[CaseResult] = config.stash.get(RESULTS, [])  # type: ignore[arg-type]
    return list(found)


def pytest_sessionfinish(session: pytest.Session, exitstatus: int) -> None:
    config = session.config
    state = config.stash.get(STATE, None)
    cases = results(config)
    if state is None or not cases or state.settings.report_dir is None:
        return
    from .report import write_reports

    write_reports(Path(state.settings.report_dir), suite_info(config), cases)

"""What a pytest run of the cases keeps, shared by the plugin and its pytest-xdist support.

One session per box (``--target`` may repeat under pytest), each box's results in the
order they ran, and on an xdist controller what the workers' sessions learnt; the
accessors the ``run`` command and the reports read them through.
"""

from __future__ import annotations

import datetime as _dt
import shlex
import sys
import time
from typing import Any

import pytest

from .. import __version__
from ..model.signature import DeathKind
from ..model.verdicts import CaseResult, RootCause, SuiteInfo
from ..runtime.run_state import STATE, SessionState
from ..runtime.settings import SuiteSettings
from .lanes import LANE_PLAN, lanes_of
from .rootcause import SessionFacts, find_root_causes

#: the run's resolved settings (every box's); each box's session holds them with its own target
SETTINGS = pytest.StashKey[SuiteSettings]()
SESSIONS = pytest.StashKey[dict[str, SessionState]]()  # target key ("" for one box) -> session
RESULTS = pytest.StashKey[dict[str, list[CaseResult]]]()
FACTS = pytest.StashKey[dict[str, SessionFacts]]()  # the controller's: what the workers' sessions learnt
STARTED = pytest.StashKey[float]()
SELECTED = pytest.StashKey[list[str]]()
CAUSES = pytest.StashKey[list[RootCause]]()
#: ``run --baseline``: the report.Baseline the run driver hands the plugin's report writers, and their comparison
BASELINE = pytest.StashKey[Any]()
BASELINE_DIFF = pytest.StashKey[Any]()
#: ``run``'s acceptance (conformance.acceptance.record.Acceptance: run ID, DUT, tester, declaration), for the reports
ACCEPTANCE = pytest.StashKey[Any]()


def target_keys(settings: SuiteSettings) -> dict[str, Any]:
    """One session per box: "" for a run against one box (or the bundled one), else each box's HOST:PORT."""
    if len(settings.targets) > 1:
        return {str(t): t for t in settings.targets}
    return {"": None}


def wants_suite(config: pytest.Config) -> bool:
    """This pytest run runs the conformance cases (not, say, the project's own tests)."""
    return bool(config.getoption("isight_target", None)) or any("conformance.cases" in str(a) for a in config.args)


def suite_info(config: pytest.Config, interrupted: bool = False, key: str = "") -> SuiteInfo:
    state = config.stash[SESSIONS].get(key) or config.stash[STATE]
    started = config.stash[STARTED]
    done = {c.id for c in results(config, key)}
    selected = config.stash.get(SELECTED, [])
    not_run = [case_id for case_id in selected if case_id not in done]
    return SuiteInfo(
        version=__version__,
        started=_dt.datetime.fromtimestamp(started, _dt.timezone.utc).isoformat(timespec="seconds"),
        duration_s=round(time.time() - started, 3),
        target=state.target_label(),
        profile=state.profile.to_dict(),
        udp_target=str(state.udp_target()) if state._target is not None and state.udp_target() else None,
        extension=state.extension_how or ("not checked" if state.settings.extension == "auto" else state.settings.extension),
        command=" ".join(shlex.quote(a) for a in sys.argv),
        complete=not (interrupted or not_run),
        cases_total=max(len(selected), len(done)),
        not_run=not_run,
        registry_version=_registry_version(),
        lanes=lanes_of(config.stash.get(LANE_PLAN, None)),
    )


def _registry_version() -> str:
    from ..protocol.clauses import REGISTRY_VERSION

    return REGISTRY_VERSION


def results(config: pytest.Config, key: str = "") -> list[CaseResult]:
    """The results of one box's cases (the first box's by default), in the order they ran."""
    found = config.stash.get(RESULTS, {})
    if key:
        return list(found.get(key, []))
    return list(found.get("", []) or next(iter(found.values()), []))


def session_facts(config: pytest.Config, key: str = "") -> SessionFacts:
    """What a box's session learnt (on an xdist controller: what its worker's session learnt)."""
    sent = config.stash.get(FACTS, {})
    if key in sent:
        return sent[key]
    return facts_of(config.stash[SESSIONS].get(key) or config.stash[STATE])


def facts_of(state: SessionState) -> SessionFacts:
    return SessionFacts(
        unresponsive=next((d.detail for d in state.deaths if d.kind is DeathKind.UNRESPONSIVE), ""),
        one_at_a_time=state.concurrency_note if state.concurrent is False else "",
        deaths=tuple(d for d in state.deaths if d.kind is not DeathKind.UNRESPONSIVE),
        first_index=state.profile.first_index,
    )


def root_causes(config: pytest.Config, key: str = "") -> list[RootCause]:
    """A box's root causes (and each explained case marked with its id)."""
    return find_root_causes(results(config, key), session_facts(config, key))

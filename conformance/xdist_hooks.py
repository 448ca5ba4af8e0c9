"""pytest-xdist support for the conformance cases (registered by the plugin only when xdist is present).

* One box's cases stay on one worker, in catalogue order: each case carries an
  ``xdist_group`` named for its box, and the run is scheduled by groups (the box has one
  shared cycle state; its cases must not run side by side).
* Every worker receives the controller's resolved settings, serialised once (``workerinput``),
  instead of parsing the flags again. The bundled box (no ``--target``) is started once, by
  the controller, and those settings name where it listens.
* ``run --lanes N`` against one slow box: the cases that share the box
  (:mod:`conformance.engine.lanes`) are dealt over N workers, and the rest run alone on one
  worker once every lane is done (:class:`LaneScheduling`).
* Each case's result travels with its test report, so the controller holds every finished
  case even when the run is cut short; what each worker's session learnt about the box
  (for the root causes) comes through ``workeroutput``. Only the controller writes reports,
  its results in catalogue order.
"""

from __future__ import annotations

import json
from dataclasses import replace
from typing import Any

import pytest

from .engine.lanes import ALONE, LANE_PLAN
from .engine.rootcause import SessionFacts
from .model.verdicts import CaseResult
from .runtime.settings import WORKER_INPUT, SuiteSettings

OUTPUT = "isight"


class XdistHooks:
    def __init__(self, config: pytest.Config) -> None:
        self.config = config

    # -- the controller ---------------------------------------------------------------------------
    @pytest.hookimpl(tryfirst=True)
    def pytest_xdist_make_scheduler(self, config: pytest.Config, log: Any) -> Any:
        """``load`` (``-n N``'s default) and ``loadgroup`` schedule by box: one box's cases on one worker."""
        from .engine.collected import SESSIONS, wants_suite

        if config.getvalue("dist") not in ("load", "loadgroup") or not wants_suite(config):
            return None  # the user chose another distribution, or this is not a run of the cases: xdist's own

        plan = config.stash.get(LANE_PLAN, None)
        if plan:
            return LaneScheduling(config, log, plan)
        return box_scheduling(config, log, [k for k in config.stash[SESSIONS] if k])

    def pytest_configure_node(self, node: Any) -> None:
        """A worker's settings: the controller's, with the bundled box the controller started (started once)."""
        from .engine.collected import SETTINGS, STATE

        state = node.config.stash[STATE]
        settings: SuiteSettings = node.config.stash[SETTINGS]
        if settings.target is None and len(settings.targets) < 2:  # the bundled box: start it once
            target, udp = state.target(), state.udp_target()
            settings = replace(settings, target=target, targets=(), udp_target=settings.udp_target or udp,
                               target_label=state.target_label())
        node.workerinput[WORKER_INPUT] = json.dumps(settings.to_dict())

    def pytest_testnodedown(self, node: Any, error: object) -> None:
        from .engine.collected import FACTS, SELECTED, SESSIONS

        sent = getattr(node, "workeroutput", {}).get(OUTPUT)
        if not sent:
            return
        data = json.loads(sent)
        config = node.config
        for key, box in data["boxes"].items():
            facts = box["facts"]
            known = config.stash[FACTS].get(key)
            config.stash[FACTS][key] = SessionFacts.from_dict(facts).merged(known)
            state = config.stash[SESSIONS].get(key)
            if state is not None and box["extension_how"]:
                state.extension_how = box["extension_how"]
        selected = config.stash[SELECTED]
        selected.extend(i for i in data["selected"] if i not in selected)

    @pytest.hookimpl(tryfirst=True)
    def pytest_runtest_logreport(self, report: pytest.TestReport) -> None:
        """On the controller: a worker's case result, as it finishes (before the run's progress sees it)."""
        sent = getattr(report, "isight_result", None)
        if sent is None or hasattr(self.config, "workerinput"):
            return
        from .engine.collected import RESULTS, SESSIONS

        key = box_key(report.nodeid, [k for k in self.config.stash[SESSIONS] if k])
        self.config.stash[RESULTS].setdefault(key, []).append(CaseResult.from_dict(sent))

    # -- a worker, and the controller's order ------------------------------------------------------
    @pytest.hookimpl(tryfirst=True)
    def pytest_sessionfinish(self, session: pytest.Session) -> None:
        config = session.config
        if not hasattr(config, "workeroutput"):
            in_catalogue_order(config)
            return
        from .engine.collected import RESULTS, SELECTED, SESSIONS, facts_of

        boxes = {}
        for key, results in config.stash.get(RESULTS, {}).items():
            if not results:
                continue
            state = config.stash[SESSIONS][key]
            boxes[key] = {"extension_how": state.extension_how, "facts": facts_of(state).to_dict()}
        config.workeroutput[OUTPUT] = json.dumps({"boxes": boxes, "selected": config.stash.get(SELECTED, [])},
                                                 default=str)


def box_key(nodeid: str, keys: list[str]) -> str:
    """The box a case's node id runs against: its parametrize id ends with the box's key
    (several boxes), else the one box of the run."""
    params = nodeid.rpartition("[")[2].rstrip("]") if nodeid.endswith("]") else ""
    return next((k for k in keys if params == k or params.endswith("-" + k)), "")


def box_scheduling(config: pytest.Config, log: Any, keys: list[str]) -> Any:
    """xdist's scope scheduling with one scope per box: a scope goes to one worker whole, in
    collection (catalogue) order. (xdist's own ``loadgroup`` names the group in a node id,
    which pytest 9 no longer lets a plugin change.)"""
    from xdist.scheduler import LoadScopeScheduling

    class BoxScheduling(LoadScopeScheduling):
        def _split_scope(self, nodeid: str) -> str:
            return "isight-box " + box_key(nodeid, keys)

    return BoxScheduling(config, log)


def in_catalogue_order(config: pytest.Config) -> None:
    """The controller's results in the order the catalogue lists the cases (lanes finish interleaved); a case
    no worker reported as selected (a run cut short) keeps its place after them."""
    from .engine.collected import RESULTS, SELECTED

    selected: list[str] = config.stash.get(SELECTED, [])
    order = {case_id: i for i, case_id in enumerate(selected)}
    for results in config.stash.get(RESULTS, {}).values():
        results.sort(key=lambda r: order.get(r.id, len(order)))


def lane_scheduler_class() -> Any:
    from xdist.scheduler import LoadScopeScheduling

    class LaneScheduling(LoadScopeScheduling):
        """Lanes first, one per worker, all at once; the cases that run alone go to one worker when
        every lane is done. A worker runs its last case only once told there is no more work, so
        every lane worker but the first is told at once, and the first keeps its lane's last case
        until the alone scope follows it."""

        def __init__(self, config: pytest.Config, log: Any, plan: dict[str, str]) -> None:
            super().__init__(config, log)
            self.plan = plan

        def _split_scope(self, nodeid: str) -> str:
            return self.plan.get(nodeid, ALONE)

        def schedule(self) -> None:
            assert self.collection_is_completed
            if self.collection is None:  # type: ignore[has-type]  # (xdist's attribute, set below)
                if not self._check_nodes_have_same_collection():
                    self.log("**Different tests collected, aborting run**")
                    return
                collection: list[str] = list(next(iter(self.registered_collections.values())))
                self.collection = collection
                for nodeid in collection:
                    self.workqueue.setdefault(self._split_scope(nodeid), {})[nodeid] = False
            self._dispatch()

        def mark_test_complete(self, node: Any, item_index: int, duration: float = 0) -> None:
            nodeid = self.registered_collections[node][item_index]
            self.assigned_work[node][self._split_scope(nodeid)][nodeid] = True
            self._dispatch()

        def _dispatch(self) -> None:
            live = [n for n in self.nodes if not n.shutting_down]
            if not live:
                return
            for node in live:  # a lane to each worker (nearly) without work
                lanes = [s for s in self.workqueue if s != ALONE]
                if lanes and self._pending_of(self.assigned_work.get(node, {})) <= 1:
                    self._give(node, lanes[0])
            if any(s != ALONE for s in self.workqueue):
                return  # more lanes than workers: the next goes to whoever is nearly done
            keeper = live[0]
            for node in live[1:]:
                node.shutdown()  # it has all it will get: it may run its last case
            others = any(self._pending_of(self.assigned_work.get(n, {})) for n in self.nodes if n is not keeper)
            if ALONE in self.workqueue and not others and self._pending_of(self.assigned_work.get(keeper, {})) <= 1:
                self._give(keeper, ALONE)
            if not self.workqueue:
                keeper.shutdown()

        def _give(self, node: Any, scope: str) -> None:
            unit = self.workqueue.pop(scope)
            self.assigned_work.setdefault(node, {})[scope] = unit
            collection = self.registered_collections[node]
            node.send_runtest_some([collection.index(nodeid) for nodeid, done in unit.items() if not done])

    return LaneScheduling


def LaneScheduling(config: pytest.Config, log: Any, plan: dict[str, str]) -> Any:  # noqa: N802 - a class, made late
    return lane_scheduler_class()(config, log, plan)

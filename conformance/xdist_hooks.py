"""pytest-xdist support for the conformance cases (registered by the plugin only when xdist is present).

* One box's cases stay on one worker, in catalogue order: each case carries an
  ``xdist_group`` named for its box, and the run is scheduled by groups (the box has one
  shared cycle state; its cases must not run side by side).
* The bundled box (no ``--target``) is started once, by the controller, and every worker
  is told where it listens.
* Workers send their results (and what their session learnt about the box, for the root
  causes) to the controller through ``workeroutput``; only the controller writes reports.
"""

from __future__ import annotations

import json
from dataclasses import replace
from typing import Any

import pytest

from .harness.target import Target
from .model.verdicts import CaseResult
from .suite.rootcause import SessionFacts
from .suite.settings import SuiteSettings

OUTPUT = "isight"


class XdistHooks:
    @staticmethod
    def worker_settings(config: pytest.Config, settings: SuiteSettings) -> SuiteSettings:
        """On a worker of a run against the bundled box: the box the controller started."""
        given = getattr(config, "workerinput", {}).get("isight_bundled")
        if not given:
            return settings
        tcp, _, udp = given.partition("|")
        return replace(settings, target=Target.parse(tcp), targets=(), udp_target=settings.udp_target or (
            Target.parse(udp) if udp else None), target_label=getattr(config, "workerinput", {}).get("isight_label", ""))

    # -- the controller ---------------------------------------------------------------------------
    @pytest.hookimpl(tryfirst=True)
    def pytest_xdist_make_scheduler(self, config: pytest.Config, log: Any) -> Any:
        """``load`` (``-n N``'s default) and ``loadgroup`` schedule by box: one box's cases on one worker."""
        from .suite.collected import SESSIONS, wants_suite

        if config.getvalue("dist") not in ("load", "loadgroup") or not wants_suite(config):
            return None  # the user chose another distribution, or this is not a run of the cases: xdist's own

        return box_scheduling(config, log, [k for k in config.stash[SESSIONS] if k])

    def pytest_configure_node(self, node: Any) -> None:
        from .suite.collected import STATE

        state = node.config.stash[STATE]
        if state.settings.target is None and len(state.settings.targets) < 2:  # the bundled box: start it once
            target, udp = state.target(), state.udp_target()
            node.workerinput["isight_bundled"] = f"{target}|{udp or ''}"
            node.workerinput["isight_label"] = state.target_label()

    def pytest_testnodedown(self, node: Any, error: object) -> None:
        from .suite.collected import FACTS, RESULTS, SELECTED, SESSIONS

        sent = getattr(node, "workeroutput", {}).get(OUTPUT)
        if not sent:
            return
        data = json.loads(sent)
        config = node.config
        for key, box in data["boxes"].items():
            config.stash[RESULTS].setdefault(key, []).extend(CaseResult.from_dict(r) for r in box["results"])
            facts = box["facts"]
            known = config.stash[FACTS].get(key)
            config.stash[FACTS][key] = SessionFacts.from_dict(facts).merged(known)
            state = config.stash[SESSIONS].get(key)
            if state is not None and box["extension_how"]:
                state.extension_how = box["extension_how"]
        selected = config.stash[SELECTED]
        selected.extend(i for i in data["selected"] if i not in selected)

    # -- a worker ---------------------------------------------------------------------------------
    @pytest.hookimpl(trylast=True)
    def pytest_sessionfinish(self, session: pytest.Session) -> None:
        config = session.config
        if not hasattr(config, "workeroutput"):
            return
        from .suite.collected import RESULTS, SELECTED, SESSIONS, facts_of

        boxes = {}
        for key, results in config.stash.get(RESULTS, {}).items():
            if not results:
                continue
            state = config.stash[SESSIONS][key]
            facts = facts_of(state)
            boxes[key] = {"results": [r.to_dict() for r in results], "extension_how": state.extension_how,
                          "facts": facts.to_dict()}
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

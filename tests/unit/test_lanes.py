"""run's lanes: which cases share the box, how they are dealt, and the scheduler's gate (pure: fake nodes)."""

from __future__ import annotations

import importlib
import inspect
from dataclasses import dataclass, field
from typing import Any

import pytest

from conformance.commands.run import parse_lanes
from conformance.engine.lanes import ALONE, ALONE_MARK, lane_name, plan, stateless_frame
from conformance.harness.concurrency import LaneProbe
from conformance.protocol import Action, encode, pose_blocks, request
from conformance.suite.record import MARKER, CaseRecord, record

pytestmark = pytest.mark.unit
CASE_MODULES = ["actions", "blocks", "boundaries", "discovery", "extension_e", "frame", "fuzzing", "robustness",
                "sequences", "session_rules", "stream_backpressure", "time_limits", "udp_datagrams", "vector_replay"]


class _Marker:
    def __init__(self, *args: Any) -> None:
        self.args = args


@dataclass
class FakeItem:
    nodeid: str
    info: CaseRecord
    alone: bool = False

    def get_closest_marker(self, name: str) -> _Marker | None:
        if name == MARKER:
            return _Marker(self.info)
        return _Marker() if name == ALONE_MARK and self.alone else None


def _item(n: int, shares: bool, alone: bool = False) -> FakeItem:
    return FakeItem(f"cases/x.py::test_{n}", record(f"A1-{n:02d}", ["A1"], "MUST", "t", "e", shares_box=shares), alone)


def test_shared_cases_are_dealt_round_robin_and_the_rest_run_alone() -> None:
    items = [_item(1, True), _item(2, False), _item(3, True), _item(4, True), _item(5, True, alone=True), _item(6, True)]
    got = plan(items, 2)  # type: ignore[arg-type]
    assert [got[i.nodeid] for i in items] == [lane_name(0), ALONE, lane_name(1), lane_name(0), ALONE, lane_name(1)]
    assert set(plan(items, 1).values()) == {ALONE}  # type: ignore[arg-type]


@pytest.mark.parametrize(("data", "stateless"), [
    (encode(request(Action.NONE)), True),
    (encode(request(Action.POSE, pose_blocks([(1.0, 2.0, 3.0, 4.0, 5.0, 6.0)] * 3))), True),
    (encode(request(Action.POSE, pose_blocks([(1.0, 2.0, 3.0, 4.0, 5.0, 6.0)] * 3)))[:20], True),  # cut short: still one pose
    (encode(request(Action.CYCLE_ON)), False),
    (encode(request(Action.CYCLE_OFF)), False),
    (encode(request(Action.NONE)) * 2, False),  # two frames
    (b"\x00\x01garbage", False),
])
def test_only_one_frame_of_a_stateless_action_shares_the_box(data: bytes, stateless: bool) -> None:
    assert stateless_frame(data) is stateless


def test_no_case_that_sets_state_or_judges_time_shares_the_box() -> None:
    shared = []
    for name in CASE_MODULES:
        module = importlib.import_module(f"conformance.cases.{name}")
        for _, fn in inspect.getmembers(module, inspect.isfunction):
            for mark in getattr(fn, "pytestmark", []):
                if mark.name == MARKER and mark.args[0].shares_box:
                    shared.append(mark.args[0])
    assert len(shared) >= 25
    for info in shared:  # S: cycle and connection rules, T: timing, E: extension state; SEQ/FUZZ/PROFILE: sessions
        assert info.family not in ("S", "T", "E") and not info.id.startswith(("SEQ", "FUZZ", "PROFILE")), info.id
        assert info.id not in ("A3-02", "F6-01", "F3-02", "R5-01", "A1-01"), info.id  # cycle actions, crowds


def test_lanes_are_used_only_for_a_slow_box_that_serves_two_connections() -> None:
    assert LaneProbe(True, 101.0, "").lanes(3) == 3
    assert LaneProbe(True, 2.0, "").lanes(3) == 1  # fast: starting workers costs more than it saves
    assert LaneProbe(False, None, "").lanes(3) == 1  # one connection at a time: never side by side


@pytest.mark.parametrize(("text", "lanes"), [("auto", 0), ("1", 1), ("4", 4)])
def test_lanes_option(text: str, lanes: int) -> None:
    assert parse_lanes(text) == lanes


@pytest.mark.parametrize("text", ["0", "-1", "x", "17", ""])
def test_a_bad_lanes_option_is_a_usage_error(text: str) -> None:
    with pytest.raises(ValueError, match="--lanes"):
        parse_lanes(text)


# -- the scheduler's gate, with fake xdist nodes ----------------------------------------------------

@dataclass(eq=False)
class FakeNode:
    name: str
    shutting_down: bool = False
    sent: list[list[int]] = field(default_factory=list)

    @property
    def gateway(self) -> Any:
        return type("Gateway", (), {"id": self.name})()

    def send_runtest_some(self, indices: list[int]) -> None:
        self.sent.append(indices)

    def shutdown(self) -> None:
        self.shutting_down = True


class FakeConfig:
    def getvalue(self, name: str) -> Any:
        return ["3*popen"] if name == "tx" else None


def _scheduler(plan_: dict[str, str], n: int = 3) -> tuple[Any, list[FakeNode]]:
    pytest.importorskip("xdist")
    from conformance.xdist_hooks import LaneScheduling

    sched = LaneScheduling(FakeConfig(), None, plan_)  # type: ignore[arg-type]
    nodes = [FakeNode(f"gw{i}") for i in range(n)]
    for node in nodes:
        sched.add_node(node)
        sched.add_node_collection(node, list(plan_))
    sched.schedule()
    return sched, nodes


def _finish(sched: Any, node: FakeNode, ids: list[str]) -> None:
    for nodeid in ids:
        sched.mark_test_complete(node, list(sched.plan).index(nodeid))


def test_the_alone_cases_start_only_when_every_lane_is_done() -> None:
    ids = [f"c{i}" for i in range(9)]
    scopes = [lane_name(0), lane_name(1), lane_name(2), lane_name(0), lane_name(1), lane_name(2), ALONE, ALONE, ALONE]
    sched, (a, b, c) = _scheduler(dict(zip(ids, scopes)))
    assert a.sent == [[0, 3]] and b.sent == [[1, 4]] and c.sent == [[2, 5]]
    assert not a.shutting_down and b.shutting_down and c.shutting_down  # b, c may run their last case
    _finish(sched, a, ["c0"])  # a holds c3 (its last) until told more
    _finish(sched, b, ["c1", "c4"])
    assert a.sent == [[0, 3]]  # c's lane is still running: nothing alone yet
    _finish(sched, c, ["c2", "c5"])
    assert a.sent == [[0, 3], [6, 7, 8]] and a.shutting_down  # then the alone cases, after a's last lane case
    _finish(sched, a, ["c3", "c6", "c7", "c8"])
    assert sched.tests_finished


def test_a_run_with_nothing_shared_runs_alone_on_one_worker() -> None:
    sched, (a, b, c) = _scheduler({"c0": ALONE, "c1": ALONE})
    assert a.sent == [[0, 1]] and a.shutting_down and b.shutting_down and c.shutting_down and not b.sent

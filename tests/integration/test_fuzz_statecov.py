"""State coverage, steering and the shared budget (conformance/fuzz/state_coverage.py, session_machine.py, session_runner.py, budget.py)."""

from __future__ import annotations

from pathlib import Path

import pytest

from conformance.fuzz.budget import Budget
from conformance.fuzz.campaign import Campaign
from conformance.fuzz.config import CampaignConfig
from conformance.fuzz.session_machine import SessionContext, machine_for
from conformance.fuzz.state_coverage import StateCoverage, Transition, space
from conformance.fuzz.strategies import Strategies
from conformance.harness.target import Target
from conformance.protocol import Action
from conformance.protocol.answers import Cycle
from tests.integration.test_fuzz_campaign import config, patched_box, target_of

pytestmark = pytest.mark.timeout(90)


def test_the_space_is_every_allowed_transition() -> None:
    core, ext = space(extension=False), space(extension=True)
    assert len(core) == 2 * 2 * 6 * 6 and len(ext) == 2 * 2 * 8 * 8  # cycle × connection × last answer × action
    assert Transition("idle", "command", "CYCLE_OFF", "REGISTER_POSE") in core
    assert Transition("idle", "stream", "CYCLE_ON", "POSE") not in core  # CycleOn accepted: the cycle is on
    assert not [t for t in core if "PROG_IDX" in (t.last, t.action)]


def test_a_transition_counts_only_when_answered_as_the_protocol_allows() -> None:
    cov = StateCoverage(extension=False, seed=1)
    cov.record(Cycle.IDLE, "command", "open", Action.NONE, 0)
    cov.record(Cycle.IDLE, "command", "open", Action.POSE, 0x1001)  # a pose must be answered 0000
    cov.record(Cycle.UNKNOWN, "command", "open", Action.TOLERANCE, 0)  # the state is not known
    cov.record(Cycle.ON, "command", "open", Action.CYCLE_OFF, 2)  # 0002 is allowed for CycleOff in a cycle
    assert set(cov.reached) == {Transition("idle", "command", "open", "NONE"),
                                Transition("on", "command", "open", "CYCLE_OFF")}
    assert len(cov.unreached()) == len(cov.space) - 2 and cov.to_dict()["reached"] == 2
    assert StateCoverage(False, seed=1).unreached() == StateCoverage(False, seed=1).unreached()


def test_steering_walks_straight_to_a_transition(tmp_path: Path) -> None:
    target = Transition("idle", "command", "CYCLE_OFF", "REGISTER_POSE")
    with patched_box() as box:
        cfg = config(target_of(box), tmp_path, extension=False)
        ctx = SessionContext(cfg, Strategies(cfg.profile, extension=False), lambda: True, StateCoverage(False))
        session = machine_for(ctx)()
        session.steer(target)
        session.steer(Transition("on", "stream", "TOLERANCE", "CYCLE_OFF"))
        session.teardown()
    assert target in ctx.coverage.reached
    assert Transition("on", "stream", "TOLERANCE", "CYCLE_OFF") in ctx.coverage.reached
    assert any("steering to" in line for line in session.log)


def test_sessions_run_from_the_first_chunk_and_the_coverage_is_reported(tmp_path: Path) -> None:
    with patched_box() as box:
        cfg = config(target_of(box), tmp_path, max_examples=300, stateful_share=0.25, extension=False)
        order: list[str] = []
        campaign = Campaign(cfg)
        run_chunk, session_chunk = campaign._run_chunk, campaign._session_chunk
        campaign._run_chunk = lambda chunk: (order.append("frames"), run_chunk(chunk))[1]  # type: ignore[method-assign]
        campaign._session_chunk = lambda: (order.append("sessions"), session_chunk())[1]  # type: ignore[method-assign]
        result = campaign.run()
    assert order[0] == "sessions" and "frames" in order  # state from the first chunk, frames interleaved
    assert result.examples == 225 and result.stateful.steps >= 75
    cov = result.stateful.coverage
    assert 10 <= cov["reached"] <= cov["of"] == len(space(False))  # the steered session walked to some
    assert result.coverage["fraction"]["values"] > 0 and result.scheduled > 0


def test_the_budget_gives_each_part_its_share() -> None:
    b = Budget(CampaignConfig(target=Target("127.0.0.1", 9), duration_s=100, stateful_share=0.2))
    assert b.next_part(0, 0) == "sessions"  # from the first second
    b.spent.update(frames=1.0, sessions=1.0)
    assert b.next_part(10, 10) == "frames"
    b.spent.update(frames=9.0)
    assert b.next_part(10, 10) == "sessions"
    assert b.next_part(10, 10, sessions_possible=False) == "frames"
    counted = Budget(CampaignConfig(target=Target("127.0.0.1", 9), max_examples=100, stateful_share=0.2))
    assert (counted.frames_budget, counted.steps_budget) == (80, 20)
    assert counted.next_part(80, 5) == "sessions" and counted.next_part(80, 20) is None
    frames_only = Budget(CampaignConfig(target=Target("127.0.0.1", 9), max_examples=10, stateful_share=0.0))
    assert frames_only.next_part(0, 0) == "frames"

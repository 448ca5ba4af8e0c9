"""R2: which input killed the box (conformance/fuzz/death.py).

Against ``DyingBox`` (``tests/integration/test_fuzz_campaign.py``): a box that stops accepting
connections after a tolerance request with three blocks. A whole campaign that meets
it is tested there.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from conformance.fuzz.config import CampaignConfig
from conformance.fuzz.death import Seen, find_killer, recover
from conformance.fuzz.executor import Executor, alive
from conformance.fuzz.strategies import Strategies
from conformance.harness.target import Target
from conformance.harness.transcript import Transcript
from conformance.protocol import Action, encode_tcp, request, tolerance_blocks
from tests.integration.test_fuzz_campaign import DyingBox

pytestmark = pytest.mark.timeout(120)

KILLER = encode_tcp(request(Action.TOLERANCE, tolerance_blocks([0.5, 1.0, 1.5])))
HARMLESS = [encode_tcp(request(Action.NONE)), encode_tcp(request(Action.TOLERANCE, tolerance_blocks([0.5])))]


def window_of(box: DyingBox) -> tuple[list[Seen], Executor]:
    """The cases since the last good liveness check, run on one connection: the last one kills the box."""
    strategies = Strategies(CampaignConfig(target=Target("127.0.0.1", box.port)).profile)
    ex = Executor(Target("127.0.0.1", box.port), strategies.profile, Transcript("FUZZ-campaign-001"))
    cases = [strategies.case("valid", "", data, f"harmless {i}") for i, data in enumerate(HARMLESS)]
    cases.append(strategies.case("valid", "", KILLER, "three tolerances"))
    window = [Seen(case, ex.run(case)) for case in cases]
    assert not alive(ex.check_alive())
    return window, ex


def test_the_killer_is_found_by_rerunning_the_suspects_after_a_restart(tmp_path: Path) -> None:
    log: list[str] = []
    box = DyingBox(full=False)
    try:
        cfg = CampaignConfig(target=Target("127.0.0.1", box.port), restart=box.restart, recover_s=2.0, log=log.append)
        window, ex = window_of(box)
        death = find_killer(cfg, window, ex, number=3)
        failure, evidence = death.failure, death.evidence
        assert death.back
        assert alive(ex.check_alive())  # brought back after the killer was confirmed
    finally:
        box.stop()
    assert (failure.number, failure.kind, failure.confirmed) == (3, "death", True)
    assert [c.wire for c in failure.cases] == [KILLER] and failure.clauses[0] == "R2"
    assert "killed the box again" in failure.message
    assert evidence is not None and evidence.case_id == "FUZZ-003" and evidence.events
    assert box.restarts == 2
    assert any("3 cases since the last good liveness check are suspects" in line for line in log)


def test_a_box_that_does_not_come_back_leaves_the_suspects_unconfirmed(tmp_path: Path) -> None:
    box = DyingBox(full=False)
    try:
        cfg = CampaignConfig(target=Target("127.0.0.1", box.port), recover_s=0.3, log=lambda _: None)
        window, ex = window_of(box)
        death = find_killer(cfg, window, ex, number=1)
        failure, evidence = death.failure, death.evidence
        assert not death.back
    finally:
        box.stop()
    odd = [s.case for s in window if s.result.anomaly]
    assert failure.kind == "death" and not failure.confirmed and evidence is None
    assert failure.cases == (odd[:1] or [s.case for s in window])
    assert ("not confirmed: the box did not come back" if odd else "one of these cases") in failure.message
    assert "--restart-cmd" in failure.message  # how to give the campaign a way to bring the box back


def test_a_restart_that_fails_is_reported_and_the_box_counts_as_not_back() -> None:
    log: list[str] = []

    def restart() -> None:
        raise OSError("no such box")

    cfg = CampaignConfig(target=Target("127.0.0.1", 9), restart=restart, log=log.append)
    ex = Executor(cfg.target, cfg.profile, Transcript("T"))
    assert recover(cfg, ex) is False
    assert log == ["fuzz: could not restart the box: no such box"]

"""The triage of a failing case (conformance/fuzz/triage.py): confirm, hand to hypothesis, state plainly, write.

Against the reference box with the planted "0000 to a pose with a wrong index" defect
(``tests/integration/test_fuzz_campaign.py``); a whole campaign's use of it is tested there.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from conformance.endpoints.loop import BoxThread
from conformance.fuzz.config import CampaignConfig
from conformance.fuzz.executor import Executor
from conformance.fuzz.strategies import Strategies
from conformance.fuzz.triage import Triage
from conformance.harness.transcript import Transcript
from conformance.protocol import Action, encode_tcp, pose_blocks, request
from tests.integration.test_fuzz_campaign import SHRUNK_BAD_INDEX, patched_box, target_of, zero_to_bad_pose_index

pytestmark = pytest.mark.timeout(120)

#: Three poses whose indexes start at 1 (the profile's first index is 0): B3, answered 0000 by the planted box.
BAD = encode_tcp(request(Action.POSE, pose_blocks([(1.0, 2.0, 3.0, 4.0, 5.0, 6.0)] * 3, first_index=1)))
NONE = encode_tcp(request(Action.NONE))


def triage_for(box: BoxThread, tmp_path: Path, log: list[str]) -> tuple[Triage, Executor, Strategies]:
    cfg = CampaignConfig(target=target_of(box), report_dir=tmp_path / "report", pcap_dir=tmp_path / "pcaps",
                         log=log.append, seed=3)
    strategies = Strategies(cfg.profile)
    ex = Executor(cfg.target, cfg.profile, Transcript("FUZZ-campaign-001"), settle_s=cfg.settle_s)
    return Triage(cfg, 3, strategies, ex, lambda: 41), ex, strategies


def test_a_confirmed_failure_goes_to_hypothesis_and_is_written_shrunk_from_its_plainest_strategy(tmp_path: Path) -> None:
    log: list[str] = []
    with patched_box(zero_to_bad_pose_index) as box:
        triage, ex, strategies = triage_for(box, tmp_path, log)
        case = strategies.case("mutation", "", BAD, "three poses, indexes from 1")
        result = ex.run(case)
        keys = {f.key for f in triage.new_failures(result)}
        assert keys and all(k.startswith("B3") for k in keys)
        connections = ex.stats.connections
        confirmed = triage.confirm(case)
        assert ex.stats.connections == connections + 1 and not ex.isolate and not ex.settle
        assert {f.key for f in confirmed.judgement.failures} == keys
        assert triage.route(result, confirmed, keys, [case]) is confirmed
        assert triage.shrinking and triage.pending is confirmed and ex.isolate and triage.failures == []
        triage.record_shrunk(confirmed)
        triage.end_shrink()
    assert not triage.shrinking and triage.pending is None and not ex.isolate
    (failure,) = triage.failures
    assert (failure.number, failure.kind, failure.shrunk, failure.confirmed) == (1, "oracle", True, True)
    assert failure.cases[0].kind.startswith("B3") and failure.hex == SHRUNK_BAD_INDEX  # rederived: no longer a mutation
    assert failure.found_after == 41 and failure.clauses[0] == "B3"
    assert failure.vector is not None and failure.vector.is_file()
    assert failure.pcap is not None and failure.pcap.read_bytes()[:4] == b"\x0a\x0d\x0d\x0a"
    assert keys <= triage.known and triage.new_failures(confirmed) == [] and triage.shrink_runs > 0
    assert any(line.startswith("fuzz: FAIL 1 [B3") for line in log)


def test_a_failure_from_its_own_strategy_is_not_searched_for_again(tmp_path: Path) -> None:
    with patched_box(zero_to_bad_pose_index) as box:
        triage, ex, strategies = triage_for(box, tmp_path, [])
        result = ex.run(strategies.case("B3-index", "B3", BAD, "three poses, indexes from 1"))
        assert triage.new_failures(result)
        assert triage.rederive(result) is None
    assert triage.shrink_runs == 0


def test_a_failure_the_fresh_connection_does_not_repeat_is_written_as_the_reused_connections(tmp_path: Path) -> None:
    with patched_box(zero_to_bad_pose_index) as box:
        triage, ex, strategies = triage_for(box, tmp_path, [])
        before = strategies.case("valid", "", NONE, "NONE")
        result = ex.run(strategies.case("mutation", "", BAD, "three poses, indexes from 1"))
        keys = {f.key for f in result.judgement.failures}
        passing = ex.run(before)  # stands for a confirmation on a fresh connection that passed
        assert not passing.judgement.failures
        assert triage.route(result, passing, keys, [before, result.case]) is None
    assert not triage.shrinking
    (failure,) = triage.failures
    assert (failure.kind, failure.confirmed, failure.shrunk) == ("context", False, False)
    assert [c.wire for c in failure.cases] == [NONE, BAD]
    assert "only after the cases before it on the same connection" in failure.message
    assert keys <= triage.known


def test_a_failure_hypothesis_could_not_replay_is_written_unshrunk(tmp_path: Path) -> None:
    with patched_box(zero_to_bad_pose_index) as box:
        triage, ex, strategies = triage_for(box, tmp_path, [])
        case = strategies.case("mutation", "", BAD, "three poses, indexes from 1")
        result = ex.run(case)
        keys = {f.key for f in result.judgement.failures}
        triage.route(result, triage.confirm(case), keys, [])
        triage.record_pending()
        triage.end_shrink()
        triage.record_pending()  # nothing pending any more: nothing written
    (failure,) = triage.failures
    assert failure.kind == "oracle" and not failure.shrunk and failure.confirmed and failure.cases[0].wire == BAD
    assert keys <= triage.known

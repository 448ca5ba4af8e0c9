"""Campaigns (conformance/fuzz/campaign.py): budget, seed, shrinking, database, deaths (R2).

The planted-defect boxes used here (and imported by the other ``test_fuzz_*`` modules)
are the reference box with one decision patched on its loop, as other tests do.
"""

from __future__ import annotations

import json
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import pytest
from hypothesis.database import DirectoryBasedExampleDatabase

from conformance.endpoints.behaviour import BoxBehaviour, BoxConfig, Decision, Reaction
from conformance.endpoints.loop import BoxThread
from conformance.fuzz.campaign import Campaign, CampaignConfig
from conformance.fuzz.strategies import Strategies
from conformance.harness.target import Target
from conformance.protocol import DEFAULT_PROFILE, Action, Frame, ProtocolError, Transport, answer

ROOT = Path(__file__).resolve().parents[2]
#: The frame the planted "0000 to a pose with a wrong index" defect must shrink to:
#: a one-block pose whose index is 1 (the profile's first index is 0), every float 0.0.
SHRUNK_BAD_INDEX = "fefe00010123010100190000" + "01" + "00" * 24 + "0000"

pytestmark = pytest.mark.timeout(120)


# -- planted defects (imported by the other fuzz tests) ------------------------------------------------


def zero_to_bad_pose_index(b: BoxBehaviour) -> None:
    """The box answers 0000 to a pose (23) whose block indexes are wrong (B3): an R1/A3 MUST broken."""
    frame = answer(Action.POSE)
    ok = Decision(Reaction.OK, frame, b.codec.encode(frame, Transport.TCP), b.codec.encode(frame, Transport.UDP),
                  "planted: 0000 to a bad index")
    original = b.decide

    def decide(event: Frame | ProtocolError, transport: Transport = Transport.TCP) -> Decision:
        h = getattr(event, "header", None)
        if isinstance(event, ProtocolError) and event.clause == "B3" and h is not None and h.action == Action.POSE:
            return ok
        return original(event, transport)

    b.decide = decide  # type: ignore[method-assign]
    b.fast_path = False  # every frame through the patched decide()


def zero_to_unknown_action(b: BoxBehaviour) -> None:
    """The box answers an unknown action (A5) with 0000, echoing it."""
    from conformance.protocol import Header, encode_raw

    original = b.decide

    def decide(event: Frame | ProtocolError, transport: Transport = Transport.TCP) -> Decision:
        h = getattr(event, "header", None)
        if isinstance(event, ProtocolError) and event.clause == "A5" and h is not None and h.start_word == 0xFEFE:
            data = encode_raw(Header(transfer_type=0x10, action=h.action))
            return Decision(Reaction.OK, None, data, data, "planted: 0000 to an unknown action")
        return original(event, transport)

    b.decide = decide  # type: ignore[method-assign]
    b.fast_path = False  # every frame through the patched decide()


@contextmanager
def patched_box(*patches: Callable[[BoxBehaviour], None], config: BoxConfig | None = None) -> Iterator[BoxThread]:
    box = BoxThread(config or BoxConfig(), host="127.0.0.1").start()
    try:
        for patch in patches:
            box.call(lambda patch=patch: patch(box.behaviour))
        yield box
    finally:
        box.stop()


class DyingBox:
    """A box that stops accepting connections when it gets a tolerance request with 3 blocks;
    ``full`` also drops every open connection. ``restart()`` brings a fresh (still deadly) one up."""

    def __init__(self, full: bool = True) -> None:
        self.full = full
        self.box = self._start(0)
        self.port = self.box.tcp_port
        self.restarts = 0

    def _start(self, port: int) -> BoxThread:
        box = BoxThread(BoxConfig(), host="127.0.0.1", port=port, udp=False).start()
        b = box.behaviour
        original = b.decide

        def decide(event: Frame | ProtocolError, transport: Transport = Transport.TCP) -> Decision:
            if isinstance(event, Frame) and event.action == Action.TOLERANCE and len(event.blocks) == 3:
                ref = box.box
                assert ref is not None and ref._server is not None
                ref._server.close()
                if self.full:
                    for conn in list(ref.connections.values()):
                        if conn.transport is not None:
                            conn.transport.abort()
            return original(event, transport)

        box.call(lambda: (setattr(b, "decide", decide), setattr(b, "fast_path", False)))
        return box

    def restart(self) -> None:
        self.box.stop()
        self.restarts += 1
        self.box = self._start(self.port)

    def stop(self) -> None:
        self.box.stop()


def config(target: Target, tmp: Path, **kw: Any) -> CampaignConfig:
    kw.setdefault("seed", 3)
    kw.setdefault("stateful_share", 0.0)
    kw.setdefault("max_examples", 2000)
    return CampaignConfig(target=target, report_dir=tmp / "report", pcap_dir=tmp / "pcaps", log=lambda _: None, **kw)


def target_of(box: BoxThread) -> Target:
    return Target("127.0.0.1", box.tcp_port)


# -- the bundled box: nothing to find ----------------------------------------------------------------------


def test_the_bundled_box_passes_a_campaign_and_the_summary_is_written(tmp_path: Path) -> None:
    lines: list[str] = []
    with patched_box() as box:
        cfg = config(target_of(box), tmp_path, max_examples=800, stateful_share=0.25,
                     udp_target=Target("127.0.0.1", box.udp_port or 0), seed=11)
        cfg.log = lines.append
        summary = Campaign(cfg).run()
    assert summary.failures == [] and summary.non_strict == []
    assert summary.examples == 600 and summary.stateful.steps >= 200
    assert summary.seed == 11 and "seed 11" in lines[0] and "--seed 11" in lines[0]
    assert summary.liveness_checks >= 600 // 64
    assert summary.by_kind.get("F7-crc", 0) + summary.by_kind.get("F7-valid", 0) > 0  # UDP cases ran
    on_disk = json.loads((tmp_path / "report" / "fuzz-summary.json").read_text())
    assert on_disk["examples"] == 600 and on_disk["examples_per_s"] > 0


def test_the_same_seed_sends_the_same_cases(tmp_path: Path) -> None:
    with patched_box() as box:
        runs = [Campaign(config(target_of(box), tmp_path / str(i), max_examples=400, seed=42)).run() for i in range(2)]
        other = Campaign(config(target_of(box), tmp_path / "o", max_examples=400, seed=43)).run()
    assert runs[0].by_kind == runs[1].by_kind
    assert other.by_kind != runs[0].by_kind


def test_a_budget_in_seconds_is_kept(tmp_path: Path) -> None:
    with patched_box() as box:
        summary = Campaign(config(target_of(box), tmp_path, max_examples=None, duration_s=3.0,
                                  stateful_share=0.3)).run()
    assert summary.examples > 0 and summary.stateful.steps > 0  # both phases ran, and it ended


# -- a planted defect: found, shrunk to one frame, written ------------------------------------------------


def test_a_planted_defect_is_found_and_shrunk_to_one_frame(tmp_path: Path) -> None:
    with patched_box(zero_to_bad_pose_index) as box:
        summary = Campaign(config(target_of(box), tmp_path, max_examples=3000, seed=3, max_failures=1)).run()
    assert len(summary.failures) == 1, summary.failures
    failure = summary.failures[0]
    assert failure.kind == "oracle" and failure.shrunk and failure.confirmed
    assert failure.clauses[0] == "B3"
    assert [c.wire.hex() for c in failure.cases] == [SHRUNK_BAD_INDEX]
    assert "MUST NOT be answered 0000" in failure.message
    doc = json.loads(Path(failure.vector).read_text())
    test = doc["testGroups"][0]["tests"][0]
    assert (test["hex"], test["result"], test["clauses"][0]) == (SHRUNK_BAD_INDEX, "invalid", "B3")
    assert Path(failure.pcap).read_bytes()[:4] == b"\x0a\x0d\x0d\x0a"


def test_distinct_failures_are_each_reported_once(tmp_path: Path) -> None:
    with patched_box(zero_to_bad_pose_index, zero_to_unknown_action) as box:
        summary = Campaign(config(target_of(box), tmp_path, max_examples=4000, seed=5)).run()
    firsts = sorted(f.clauses[0] for f in summary.failures)
    assert "B3" in firsts and "A5" in firsts, summary.failures
    assert len(firsts) == len(set(firsts))


def test_the_database_replays_a_failure_first(tmp_path: Path) -> None:
    db = DirectoryBasedExampleDatabase(tmp_path / "db")
    # every category, hypothesis's own cases only: the boundary schedule (which sends a wrong index among its
    # first cases, and whose finds are not saved) would find the defect at once in both campaigns
    every = tuple(Strategies(DEFAULT_PROFILE).categories())
    with patched_box(zero_to_bad_pose_index) as box:
        first = Campaign(config(target_of(box), tmp_path / "1", max_examples=3000, seed=3, database=db,
                                max_failures=1, categories=every)).run()
        again = Campaign(config(target_of(box), tmp_path / "2", max_examples=3000, seed=99, database=db,
                                max_failures=1, categories=every)).run()
    assert first.failures and again.failures
    assert again.failures[0].cases[0].wire.hex() == SHRUNK_BAD_INDEX
    assert again.failures[0].found_after <= 32 < first.failures[0].found_after  # the replay came first


# -- R2: a box that dies -------------------------------------------------------------------------------------


@pytest.mark.parametrize("full", [True, False], ids=["dies", "stops-accepting"])
def test_a_box_that_dies_is_confirmed_on_the_restarted_box_and_the_campaign_goes_on(tmp_path: Path, full: bool) -> None:
    box = DyingBox(full=full)
    try:
        summary = Campaign(config(Target("127.0.0.1", box.port), tmp_path, max_examples=1500, seed=5,
                                  restart=box.restart, recover_s=2.0, liveness_every=16)).run()
    finally:
        box.stop()
    assert summary.stopped is None and summary.examples == 1500  # brought back, the campaign went on to its end
    deaths = [f for f in summary.failures if f.kind == "death"]
    failure = deaths[0]
    assert failure.confirmed and failure.clauses[0] == "R2"
    (killer,) = failure.cases
    assert killer.wire[:10] == bytes.fromhex("fefe0001012502030005")  # a tolerance request, 3 blocks
    assert len(deaths) == len({d.keys[-1] for d in deaths})  # the same death is not reported twice
    assert box.restarts >= 2 and summary.restarts >= 1  # once to confirm, once to go on


def test_a_dead_box_that_does_not_come_back_is_caught_within_the_liveness_interval(tmp_path: Path) -> None:
    box = DyingBox(full=False)
    try:
        summary = Campaign(config(Target("127.0.0.1", box.port), tmp_path, max_examples=5000, seed=5,
                                  liveness_every=16, recover_s=0.3)).run()
    finally:
        box.stop()
    (failure,) = summary.failures
    assert failure.kind == "death" and not failure.confirmed
    assert 1 <= len(failure.cases) <= 16  # the suspects: the cases since the last good liveness check
    assert any(c.wire.hex().startswith("fefe000101250203") for c in failure.cases)
    assert "--restart-cmd" in failure.message and "--restart-cmd" in summary.hint

"""Stateful fuzzing (conformance/fuzz/session_runner.py): sessions over command and stream connections."""

from __future__ import annotations

import json
import os
from pathlib import Path

import pytest

from conformance.endpoints.behaviour import BoxBehaviour, BoxConfig, Cycle, Decision, Reaction
from conformance.fuzz.campaign import Campaign
from conformance.fuzz.session_runner import run_stateful
from conformance.fuzz.strategies import Strategies
from conformance.protocol import Action, ErrorCode, Frame, ProtocolError, Transport, answer
from conformance.suite.sequence import load as load_sequence
from tests.integration.test_fuzz_campaign import config, patched_box, target_of

pytestmark = pytest.mark.timeout(90)


def pose_error_during_a_cycle(b: BoxBehaviour) -> None:
    """S3 broken: while a cycle is on, poses are answered 1001."""
    frame = answer(Action.POSE, ErrorCode.POSE_ERROR)
    bad = Decision(Reaction.POSE_ERROR, frame, b.codec.encode(frame, Transport.TCP), None, "planted")
    original = b.decide

    def decide(event: Frame | ProtocolError, transport: Transport = Transport.TCP) -> Decision:
        decision = original(event, transport)
        if isinstance(event, Frame) and event.action == Action.POSE and b.state is Cycle.ON:
            return bad
        return decision

    b.decide = decide  # type: ignore[method-assign]
    b.fast_path = False  # every frame through the patched decide()


def test_sessions_against_the_bundled_box_pass(tmp_path: Path) -> None:
    with patched_box() as box:
        summary = Campaign(config(target_of(box), tmp_path, stateful_share=1.0, max_examples=500, seed=8)).run()
    assert summary.failures == [] and summary.examples == 0
    assert summary.stateful.runs >= 2 and summary.stateful.steps >= 500


def test_a_state_dependent_defect_is_found_shrunk_and_written_as_a_sequence(tmp_path: Path) -> None:
    with patched_box(pose_error_during_a_cycle) as box:
        summary = Campaign(config(target_of(box), tmp_path, stateful_share=1.0, max_examples=2000, seed=8)).run()
    (failure,) = summary.failures
    assert failure.kind == "stateful" and (failure.shrunk or "walked to alone" in failure.message)
    steps = failure.steps
    assert any(s.startswith("CycleOn") for s in steps) and any("pose" in s for s in steps)
    assert len(steps) <= 8, steps  # opens, the initial CycleOff, CycleOn, the pose (and little else)
    seq = load_sequence(failure.sequence)
    assert seq.id == "SEQ-FUZZ-001"
    doc = json.loads(Path(failure.sequence).read_text())
    assert doc["steps"][0] == {"open": "command", "target": "command"}
    vector = json.loads(Path(failure.vector).read_text())
    assert vector["testGroups"][0]["tests"][0]["result"] == "valid"  # the pose was a well-formed request
    assert Path(failure.pcap).is_file()
    # the sequence is a case of the suite: it fails against the broken box and passes against the reference
    verdicts = {}
    with patched_box(pose_error_during_a_cycle) as broken, patched_box() as good:
        for name, box in (("broken", broken), ("good", good)):
            report = tmp_path / name
            code = pytest.main(["-c", os.devnull, "--rootdir", str(tmp_path), "--pyargs", "conformance.cases",
                                "-p", "no:cacheprovider", "-p", "no:terminal", "--target", f"127.0.0.1:{box.tcp_port}",
                                f"--sequence={failure.sequence}", "--cases", "SEQ-FUZZ-*", "--isight-capture", "off",
                                "--report-dir", str(report)])
            assert code in (0, 1)
            cases = json.loads((report / "summary.json").read_text())["cases"]
            verdicts[name] = {c["id"].split("[")[0]: c["verdict"] for c in cases}["SEQ-FUZZ-001"]
    assert verdicts == {"broken": "FAIL", "good": "PASS"}


def test_without_the_extension_no_26_or_27_is_sent(tmp_path: Path) -> None:
    from conformance.harness.transcript import Kind, Transcript

    transcript = Transcript("T")
    with patched_box(config=BoxConfig(extension=False)) as box:
        summary = Campaign(config(target_of(box), tmp_path, stateful_share=1.0, max_examples=300, seed=2,
                                  extension=False, categories=("B3-index",), transcript=transcript)).run()
    assert summary.failures == []
    sent = [e.data for e in transcript.events if e.kind == Kind.SEND and len(e.data) >= 6 and e.data[:2] == b"\xfe\xfe"]
    assert sent and not [d for d in sent if d[4] == 0x01 and d[5] in (0x26, 0x27)]


def test_run_stateful_keeps_to_the_budget_it_is_given_and_returns_what_it_did(tmp_path: Path) -> None:
    asked: list[int] = []

    def budget(steps: int) -> bool:
        asked.append(steps)
        return steps < 60

    with patched_box() as box:
        cfg = config(target_of(box), tmp_path, stateful_share=1.0)
        result = run_stateful(cfg, Strategies(cfg.profile), 8, budget, number=1)
    assert result.failures == [] and result.stopped == ""
    assert result.runs >= 1 and result.steps >= 60
    assert asked[0] == 0 and asked[-1] == result.steps  # asked before the first step, and once the budget was spent


def test_a_session_failure_comes_back_in_the_result_with_the_number_it_was_given(tmp_path: Path) -> None:
    with patched_box(pose_error_during_a_cycle) as box:
        cfg = config(target_of(box), tmp_path, stateful_share=1.0)
        result = run_stateful(cfg, Strategies(cfg.profile), 8, lambda steps: steps < 2000, number=4)
    (failure,) = result.failures
    assert result.stopped == "failure" and failure.kind == "stateful" and failure.number == 4
    assert failure.sequence is not None and failure.sequence.name == "fuzz-failure-004.sequence.json"
    assert load_sequence(failure.sequence).id == "SEQ-FUZZ-004"
    assert result.steps > 0 and result.runs > 0

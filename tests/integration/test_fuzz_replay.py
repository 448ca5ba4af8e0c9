"""Replay (conformance/fuzz/replay.py): vector files resent to a box, judged by the fuzz oracle."""

from __future__ import annotations

from pathlib import Path

import pytest

from conformance.evidence.vectors_file import REPO_VECTORS
from conformance.fuzz.failure_files import Failure, write_vectors
from conformance.fuzz.replay import load_files, replay, summary_line
from conformance.fuzz.strategies import Strategies
from conformance.harness.target import Target
from conformance.protocol import Action, Profile, encode, pose_blocks, request, tolerance_blocks
from tests.integration.test_fuzz_campaign import DyingBox, patched_box, zero_to_bad_pose_index

pytestmark = pytest.mark.timeout(60)
GOLDEN = sorted((REPO_VECTORS / "frames").glob("*.json"))
S = Strategies(Profile())
BAD_INDEX = S.case("B3-index", "B3", encode(request(Action.POSE, pose_blocks([(0.0,) * 6], 1))), "bad index")
POSE = S.case("valid", "", encode(request(Action.POSE, pose_blocks([(1.0,) * 6]))), "pose")


def _file(tmp: Path, *cases: object, kind: str = "oracle") -> Path:
    return write_vectors(tmp / "v.json", Failure(1, kind, ["B3"], "test", list(cases)), Profile(), "test")  # type: ignore[arg-type]


def test_the_golden_vectors_all_pass_against_the_bundled_box() -> None:
    vectors = load_files(GOLDEN)
    with patched_box() as box:
        results = replay(vectors, Target("127.0.0.1", box.tcp_port), Profile(),
                         udp_target=Target("127.0.0.1", box.udp_port or 0))
    by = {}
    for r in results:
        by.setdefault(r.status, []).append(r)
    assert not by.get("FAIL") and not by.get("NOT RUN"), [r.line() for r in by.get("FAIL", [])]
    assert len(by["OK"]) > 100
    skipped = {r.why.split(":")[0].split(";")[0] for r in by["SKIP"]}
    assert any("box→robot" in w for w in skipped) and any("first index 1" in r.why for r in by["SKIP"])
    assert summary_line(results).startswith(f"replay: {len(vectors)} vectors: ")


def test_a_fuzz_failure_fails_against_the_broken_box_and_passes_against_the_reference(tmp_path: Path) -> None:
    path = _file(tmp_path, BAD_INDEX, POSE)
    vectors = load_files([path])
    with patched_box(zero_to_bad_pose_index) as broken, patched_box() as good:
        now_broken = replay(vectors, Target("127.0.0.1", broken.tcp_port), Profile())
        now_good = replay(vectors, Target("127.0.0.1", good.tcp_port), Profile())
    assert [r.status for r in now_broken] == ["FAIL", "OK"]
    assert "answered box→robot POSE err=0x0000" in now_broken[0].did and "B3" in now_broken[0].why
    assert [r.status for r in now_good] == ["OK", "OK"]
    assert load_files([path], [2])[0].tc_id == 2


def test_skips_truncation_and_one_connection(tmp_path: Path) -> None:
    cut = S.case("F5-truncated", "F5", POSE.data[:20], "cut", eof=True)
    udp_less = load_files([p for p in GOLDEN if p.name == "udp.json"])
    with patched_box() as box:
        target = Target("127.0.0.1", box.tcp_port)
        assert {r.status for r in replay(udp_less, target, Profile())} == {"SKIP"}  # no --udp-target
        (result,) = replay(load_files([_file(tmp_path, cut)]), target, Profile())
        assert result.status == "OK" and "closed" in result.did  # the stream ended inside a frame
        one = replay(load_files([_file(tmp_path, POSE, BAD_INDEX, POSE, kind="context")]), target, Profile(),
                     one_connection=True)
    assert [r.status for r in one] == ["OK", "OK", "OK"]


def test_a_box_that_dies_fails_r2_and_the_rest_is_not_run(tmp_path: Path) -> None:
    kill = S.case("valid", "", encode(request(Action.TOLERANCE, tolerance_blocks([0.1, 0.2, 0.3]))), "3 tolerances")
    box = DyingBox(full=True)
    try:
        results = replay(load_files([_file(tmp_path, POSE, kill, POSE)]), Target("127.0.0.1", box.port),
                         Profile(time_out_ms=500))
    finally:
        box.stop()
    assert [r.status for r in results] == ["OK", "FAIL", "NOT RUN"]
    assert "R2" in results[1].why

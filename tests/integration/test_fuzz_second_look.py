"""A probe left unanswered past time_out, looked at again (conformance/fuzz/second_look.py), against boxes of
tests/impls served in this process: a legal box that completes a short frame with the probe's first bytes is not
judged R6 (a second probe is answered); a box that hangs after bad bytes still is (the second probe silent too, a
fresh connection answered); a box whose whole loop stalls once is recorded as a stall, not charged to the bytes."""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import replace

import pytest

from conformance.fuzz import second_look
from conformance.fuzz.executor import Executor
from conformance.fuzz.strategies import Strategies
from conformance.harness.client import Silence
from conformance.harness.target import Target
from conformance.harness.transcript import Transcript
from conformance.model.verdicts import Verdict
from conformance.protocol import Profile
from tests.impls import boxcore
from tests.impls.box import variant
from tests.impls.boxcore import ThreadBox

pytestmark = pytest.mark.timeout(60)
P = Profile().replace(time_out_ms=1000)
S = Strategies(P, extension=True, udp=False)
SHORT = bytes.fromhex("fefe0000 0000 0000 0000 0000".replace(" ", ""))  # a header with version 0000, no check field


@contextmanager
def serving(name: str) -> Iterator[tuple[ThreadBox, Executor]]:
    box = ThreadBox(replace(variant(name).choices, time_out=1.0)).start()
    ex = Executor(Target("127.0.0.1", box.port), P, Transcript("T"))
    try:
        yield box, ex
    finally:
        ex.close()
        box.stop()


def test_a_box_that_completes_a_short_frame_with_the_probe_is_not_judged_r6() -> None:
    with serving("completes-short") as (box, ex):
        result = ex.run(S.case("t", "", SHORT, "12 bytes, version 0000"))
    assert isinstance(result.end, Silence), "the first probe went unanswered: its first bytes completed the frame"
    assert result.verdict is Verdict.PASS, result.judgement.describe()
    assert second_look.take(("127.0.0.1", box.port)) == []


def test_a_box_that_hangs_after_bad_bytes_is_still_non_strict_r6_with_both_probes_named() -> None:
    with serving("no-resync") as (_box, ex):
        result = ex.run(S.case("t", "", SHORT, "12 bytes, version 0000"))
    [hang] = [f for f in result.judgement.findings if f.key == "end/hang"]
    assert hang.verdict is Verdict.NON_STRICT and hang.clause == "R6"
    assert "a second probe on the same connection went unanswered too" in hang.observed


def test_a_box_whose_whole_loop_stalls_is_a_stall_not_a_verdict_on_the_bytes(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(boxcore, "STALL_AT", 1)
    monkeypatch.setattr(boxcore, "STALL_ON_CONN", 1)
    monkeypatch.setattr(boxcore, "STALL_S", 1.6)  # past the 1 s time_out, and a fresh connection held as well
    with serving("stall-once") as (box, ex):
        result = ex.run(S.case("t", "", SHORT, "12 bytes, version 0000"))
        [stall] = second_look.take(("127.0.0.1", box.port))
    assert isinstance(result.end, Silence) and result.verdict is Verdict.PASS, result.judgement.describe()
    assert 1.0 <= stall.lasted_s <= 3.0 and stall.after.startswith("fe fe 00 00")
    assert "fresh connection" in stall.affected and stall.example == 1

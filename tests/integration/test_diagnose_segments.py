"""Segmentation isolated (:mod:`conformance.diagnose.segments`) against boxes of tests/impls served in this process:
a box that loses a read shorter than a header at the start of a frame is caught at the split inside the header,
one that discards the rest of a read after a frame at several frames in one segment, and a conforming box
passes every trial (nothing isolated)."""

from __future__ import annotations

import time

import pytest

from conformance.diagnose.experiments import Prober
from conformance.diagnose.hypotheses import Experiment
from conformance.diagnose.segments import Segments
from conformance.harness.target import Target
from conformance.model.verdicts import CaseResult, Level, Verdict
from conformance.protocol import Profile
from tests.impls.boxcore import ThreadBox
from tests.impls.policy import random_choices

FAST = {"latency": "0", "cycle_on_latency": "0", "writer": "whole", "udp": "off", "stream_port": "same"}


@pytest.mark.parametrize("defect, kind", [("split-header-lost", "split-header"), ("drops-rest-of-read", "coalesced"),
                                          (None, None)])
def test_the_split_point_or_the_segment_is_isolated(defect: str | None, kind: str | None) -> None:
    choices = random_choices(3, fixed=FAST)
    if defect is not None:
        choices = choices.with_defect(defect)
    profile = Profile().replace(first_index=int(choices.first_index), time_out_ms=1000)
    member = CaseResult("R3-02[1]", "R3-02", ("R3", "A1"), Level.MUST, Verdict.FAIL, "seen")
    box = ThreadBox(choices).start()
    try:
        segments = Segments(Prober(Target("127.0.0.1", box.port), profile, 1.0, time.monotonic() + 20))
        exp = Experiment("isolate", "")
        found = segments.isolate(exp, [member])
    finally:
        box.stop()
    assert len(exp.exchanges) >= 2  # the whole frame and at least one cut, each recorded
    if kind is None:
        assert found is None
        return
    assert found is not None and found.detail["segmentation"] == kind, found
    assert "unconfirmed" not in found.title and found.detail["trials"]["whole"] == ["ok", 0]

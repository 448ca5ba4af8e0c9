"""The timing experiments against boxes of tests/impls served in this process (sockets and threads): a CycleOn
answered past time_out while another connection is answered at once is a late answer, not a stall or a silence;
a box that stops answering a connection after its 20th request shows that count, again on a fresh connection."""

from __future__ import annotations

import time
from dataclasses import replace

from conformance.diagnose import timing
from conformance.diagnose import timing_judge as J
from conformance.diagnose.experiments import Prober
from conformance.harness.target import Target
from conformance.protocol import Action, Profile
from tests.impls.boxcore import ThreadBox
from tests.impls.policy import random_choices
from tests.impls.systematic import FIXED

FAST = {"latency": "0", "writer": "whole"}


def _prober(port: int, first_index: int, time_out_s: float) -> Prober:
    profile = Profile().replace(first_index=first_index, time_out_ms=int(time_out_s * 1000))
    return Prober(Target("127.0.0.1", port), profile, time_out_s, time.monotonic() + 10.0)


def test_a_cycle_on_answered_past_time_out_with_other_connections_served_is_a_late_answer() -> None:
    choices = replace(random_choices(3, fixed=FIXED | FAST | {"cycle_on_latency": "0.6 time_out",
                                                              "cycle_on_ready": "ready"}), time_out=1.0)
    box = ThreadBox(choices).start()  # CycleOn answered after 0.6 s; the suite's time_out here 0.4 s
    try:
        found = timing.late(_prober(box.port, int(choices.first_index), 0.4), int(Action.CYCLE_ON))
    finally:
        box.stop()
    assert [m.kind for m in found.mechanisms] == [J.LATE], found.stories
    m = found.mechanisms[0]
    assert 0.5 < m.detail["latency_s"] < 1.0 and m.detail["other_s"] < 0.3
    assert "CycleOn" in m.title and "time_out" in m.title
    assert found.stories[J.STALL][0].value == "ruled out"


def test_a_per_connection_request_limit_is_counted_to_its_first_silence_and_replayed() -> None:
    choices = random_choices(5, fixed=FIXED | FAST | {"cycle_on_latency": "0"}).with_defect("connection-limit-20")
    box = ThreadBox(choices).start()
    try:
        found = timing.budget(_prober(box.port, int(choices.first_index), 1.0))
    finally:
        box.stop()
    assert [(m.kind, m.detail["n"]) for m in found.mechanisms] == [(J.BUDGET, 20)], found.stories
    assert "20th request" in found.mechanisms[0].title

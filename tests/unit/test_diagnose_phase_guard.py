"""A defect of the diagnose phase never costs a run its reports (diagnose/phase.run_phase): the root causes are
kept as read from the verdicts, each with the error named."""

from __future__ import annotations

import pytest

from conformance.diagnose import phase
from conformance.engine.rootcause import SessionFacts
from conformance.harness.target import Target
from conformance.model.verdicts import RootCause
from conformance.runtime.run_state import SessionState
from conformance.runtime.settings import SuiteSettings


def test_a_phase_that_raises_keeps_the_causes_as_read(monkeypatch: pytest.MonkeyPatch,
                                                      capsys: pytest.CaptureFixture[str]) -> None:
    def broken(*args: object, **kwargs: object) -> None:
        raise ValueError("3 is not a valid Action")

    monkeypatch.setattr(phase, "diagnose", broken)
    state = SessionState(SuiteSettings(target=Target("127.0.0.1", 9)))
    cause = RootCause("RC1", ("T1",), "The box does not answer POSE within time_out", "e", [], kind="unanswered")
    [kept] = phase.run_phase(state, [], [cause], SessionFacts())
    assert kept.title == "The box does not answer POSE within time_out"
    assert kept.diagnosis is not None and "3 is not a valid Action" in kept.diagnosis["error"]
    assert "diagnose phase stopped" in capsys.readouterr().err

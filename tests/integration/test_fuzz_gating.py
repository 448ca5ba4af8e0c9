"""CI gating options against the bundled box (threads, sockets): --budget-cases is a case count, --until-first."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from conformance.commands import main

pytestmark = pytest.mark.timeout(180)


def test_a_case_budget_is_the_same_run_however_fast_the_machine(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                                                monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)
    runs = []
    for name in ("a", "b"):
        code = main(["fuzz", "--budget-cases", "250", "--seed", "7", "--database", "none", "--report-dir", name,
                     "--until-first", "--quiet"])
        assert code == 0, capsys.readouterr().out
        runs.append(json.loads((tmp_path / name / "fuzz-summary.json").read_text()))
    a, b = runs
    assert a["examples"] == 200 and 50 <= a["stateful"]["steps"] <= 50 + 16  # 250 × (1 - 0.2) frames, the rest steps
    assert a["by_kind"] == b["by_kind"] and a["coverage"] == b["coverage"]  # the same cases, twice
    assert a["stopped"] is None and a["failures"] == []


def test_a_case_budget_and_a_duration_are_exclusive(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as exc:
        main(["fuzz", "--budget-cases", "5", "--duration", "1"])
    assert exc.value.code == 2
    assert "not allowed with argument" in capsys.readouterr().err

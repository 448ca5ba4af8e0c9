"""The vendor's loop end to end: run the suite against a box with one planted systematic defect, read the
headline (a mechanism confirmed by experiment), then ``replay`` its ``rootcause-N.json``: "still present"
(exit 1) against the broken box, "fixed" (exit 0) against the same box without the defect.

A CI-sized sample of ``benchmarks/bench_rootcause.py`` (which runs every planted defect): two boxes whose
catalogue verdicts two stories fit (a count read as signed looks like indexes judged wrongly; a pose
answered twice looks like the action never echoed). About a minute each on a loaded 2-core machine."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from dataclasses import replace
from pathlib import Path
from typing import Any

import pytest

from tests.impls.boxcore import ThreadBox
from tests.impls.policy import Choices, random_choices
from tests.impls.systematic import FIXED, SYSTEMATIC

ROOT = Path(__file__).resolve().parents[2]
ENV = {**os.environ, "PYTHONPATH": str(ROOT)}


def suite(args: list[str], cwd: Path, timeout: float = 400) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "conformance", *args], capture_output=True, text=True,
                          timeout=timeout, cwd=cwd, env=ENV)


def run_against(choices: Choices, report: Path) -> dict[str, Any]:
    with ThreadBox(choices) as box:
        done = suite(["run", "--target", f"127.0.0.1:{box.port}", "--quiet", "--capture", "off",
                      "--report-dir", str(report), *choices.suite_args()], report.parent)
    assert done.returncode == 1, done.stdout[-2000:] + done.stderr[-2000:]
    doc: dict[str, Any] = json.loads((report / "summary.json").read_text())
    return doc


def replay(choices: Choices, repro: Path) -> subprocess.CompletedProcess[str]:
    with ThreadBox(choices) as box:
        return suite(["replay", str(repro), "--target", f"127.0.0.1:{box.port}", *choices.suite_args()],
                     repro.parent, timeout=120)


@pytest.mark.impls(seconds=90)
@pytest.mark.parametrize("defect, words", [("signed-count", "128 or more blocks (count read as signed?)"),
                                           ("pose-twice", "Answers every pose (23) twice")])
def test_the_headline_is_the_confirmed_mechanism_and_replay_says_when_it_is_fixed(
        defect: str, words: str, tmp_path: Path) -> None:
    choices = random_choices(20261127, fixed=FIXED).with_defect(defect)
    doc = run_against(choices, tmp_path / "report")
    first = doc["root_causes"][0]
    assert first["confirmed"] is True and first["diagnosis"]["mechanism"] == SYSTEMATIC[defect].mechanism, first["title"]
    assert words in first["title"], first["title"]
    assert not any(rc["confirmed"] is False and i == 0 for i, rc in enumerate(doc["root_causes"]))
    assert first["diagnosis"]["phase_s"] <= 20
    considered = {h["key"]: h["status"] for h in first["diagnosis"]["hypotheses"]}
    assert considered[SYSTEMATIC[defect].mechanism] == "confirmed" and "ruled out" in considered.values()
    repro = tmp_path / "report" / first["diagnosis"]["repro"]["file"]
    assert repro.exists()
    broken = replay(choices, repro)
    assert broken.returncode == 1 and "still present" in broken.stdout, broken.stdout + broken.stderr
    fixed = replay(replace(choices, defect=None), repro)
    assert fixed.returncode == 0 and "fixed" in fixed.stdout, fixed.stdout + fixed.stderr

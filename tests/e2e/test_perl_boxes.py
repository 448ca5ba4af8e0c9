"""The independent Perl boxes of tests/impls/perl (written from docs/PROTOCOL.md alone, by a session that never read
the suite): the legal ones clean, and the two tuning defects the catalogue once missed found by the cases added for
them (E3-02: the run's first result request, before any cycle; R7-01[truncated-after-whole]).

The held-out half (tests/impls/perl/heldout) is not used here: ``benchmarks/bench_heldout.py --boxes
tests/impls/perl`` scores it, once."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest

ROOT = Path(__file__).resolve().parents[2]
BOX = ROOT / "tests" / "impls" / "perl" / "box.pl"

pytestmark = [pytest.mark.e2e, pytest.mark.impls,
              pytest.mark.skipif(shutil.which("perl") is None or not BOX.exists(), reason="needs perl and tests/impls/perl")]


def _run(name: str, tmp_path: Path, *cases: str) -> dict[str, dict[str, Any]]:
    """Serve box ``name`` and run the cases matching ``cases`` against it (TCP and UDP); the cases by id."""
    box = subprocess.Popen(["perl", str(BOX), name, "--port", "0"], stdout=subprocess.PIPE, text=True)
    try:
        assert box.stdout is not None
        words = box.stdout.readline().split()
        args = ["--target", words[words.index("tcp") + 1], "--udp-target", words[words.index("udp") + 1]]
        if "args" in words:
            args += words[words.index("args") + 1:]
        selection = [a for c in cases for a in ("--cases", c)]
        run = subprocess.run([sys.executable, "-m", "conformance", "run", *args, *selection, "--quiet", "--capture",
                              "off", "--report-dir", str(tmp_path)], capture_output=True, text=True, timeout=240,
                             cwd=ROOT)
    finally:
        box.terminate()
        box.wait(10)
    assert run.returncode in (0, 1), run.stderr[-2000:]
    summary = json.loads((tmp_path / "summary.json").read_text())
    return {c["id"]: c for c in summary["cases"]}


@pytest.mark.impls(seconds=20)
@pytest.mark.parametrize("name", ["legal-p", "legal-q"])
def test_a_legal_perl_box_is_clean_on_the_cases_added_for_the_perl_boxes(tmp_path: Path, name: str) -> None:
    cases = _run(name, tmp_path, "E3-*", "R7-*")
    bad = {k: c["verdict"] for k, c in cases.items() if c["verdict"] in ("FAIL", "NON-STRICT", "ERROR")}
    assert not bad, bad
    assert cases["R7-01[truncated-after-whole]"]["verdict"] == "PASS"


@pytest.mark.impls(seconds=15)
def test_a_box_answering_result_code_0_before_its_first_cycle_fails_e3_02(tmp_path: Path) -> None:
    cases = _run("p11", tmp_path, "E3-02")
    case = cases["E3-02"]
    assert case["verdict"] == "FAIL" and "E3" in case["clauses"], case
    # the box's answer: one type-03 block holding ResultCode 0 (the robot's empty initial value)
    assert str(case["received_hex"]).replace(" ", "").endswith("00000000" + "0000"), case


@pytest.mark.impls(seconds=15)
def test_a_box_completing_a_short_datagram_from_the_previous_one_fails_r7(tmp_path: Path) -> None:
    cases = _run("p16", tmp_path, "R7-*")
    assert cases["R7-01[truncated-after-whole]"]["verdict"] == "FAIL", cases
    assert cases["R7-01[truncated]"]["verdict"] == "PASS", cases  # alone, a short datagram is dropped

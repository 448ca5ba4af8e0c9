"""Bounded time whatever the box does, backpressure, and timing verdicts (issue 25), end to end.

Each test serves one of the independent boxes of ``tests/impls`` in-process and runs the
real command line (``python -m conformance run``) against it with a few cases; the
certify test runs ``certify-robot`` against the 45 Hz robot, as the matrix does.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
from pathlib import Path

import pytest

from tests.impls.box import start_box
from tests.impls.expectations import EXPECTATIONS
from tests.impls.matrix import ROOT, run_robot


def _run(box: str, tmp_path: Path, *cases: str) -> dict[str, dict[str, object]]:
    """The cases' records (id -> summary.json case) of a run against ``box``."""
    selected = [arg for glob in cases for arg in ("--cases", glob)]
    with start_box(box) as served:
        cmd = [sys.executable, "-m", "conformance", "run", "--target", f"127.0.0.1:{served.port}", "--quiet",
               "--capture", "off", "--report-dir", str(tmp_path / "report"), *selected,
               *served.choices.suite_args()]
        done = subprocess.run(cmd, capture_output=True, text=True, timeout=400, cwd=ROOT)
    assert done.returncode in (0, 1), done.stderr[-2000:]
    summary = json.loads((tmp_path / "report" / "summary.json").read_text())
    return {str(c["id"]): c for c in summary["cases"]}


def _verdicts(cases: dict[str, dict[str, object]]) -> dict[str, str]:
    return {k: str(c["verdict"]) for k, c in cases.items()}


@pytest.mark.impls(seconds=40)
def test_a_box_dropping_what_a_short_send_left_fails_the_backpressure_cases(tmp_path: Path) -> None:
    cases = _run("short-send-drops", tmp_path, "S6-03", "S6-04")
    for cid in ("S6-03", "S6-04"):
        case = cases[cid]
        assert case["verdict"] == "FAIL", case
        assert set(case["judged"]) & {"S6", "F5", "A1"}, case  # type: ignore[arg-type]
        assert "lost" in str(case["message"]) or "cut" in str(case["message"]), case
        assert case["received_hex"], case  # the bytes are given


@pytest.mark.impls(seconds=40)
def test_a_legal_box_passes_the_backpressure_cases(tmp_path: Path) -> None:
    verdicts = _verdicts(_run("byte-by-byte", tmp_path, "S6-0[234]"))
    assert {k: v for k, v in verdicts.items() if k.startswith("S6")} == {"S6-02": "PASS", "S6-03": "PASS",
                                                                        "S6-04": "PASS"}


@pytest.mark.impls(seconds=60)
def test_a_sticky_error_is_failed_twice_then_cut_short(tmp_path: Path) -> None:
    """After a refusal every answer carries its code: the probe behind malformed bytes never gets its 0000.
    The first cases of the pattern wait time_out and FAIL A1; later ones are cut short, INCONCLUSIVE."""
    cases = _run("sticky-error", tmp_path, "B5-01*")
    failed = [c for c in cases.values() if c["verdict"] == "FAIL" and "A1" in c["judged"]]  # type: ignore[operator]
    cut = [c for c in cases.values() if c["verdict"] == "INCONCLUSIVE" and "no 0000 followed" in str(c["message"])]
    assert failed and len(cut) >= 5, _verdicts(cases)
    assert all("PASS" != c["verdict"] for c in failed + cut)


@pytest.mark.impls(seconds=60)
def test_a_box_dropping_every_seventh_answer_is_failed_then_cut_short(tmp_path: Path) -> None:
    cases = _run("drops-frames", tmp_path, "A1-0[12]", "B3-03*", "T1-01", "S3-02", "E5-01")
    failed = [k for k, c in cases.items() if c["verdict"] == "FAIL"]
    cut = [k for k, c in cases.items() if c["verdict"] == "INCONCLUSIVE" and "after 6 answer(s)" in str(c["message"])]
    assert len(failed) >= 2 and cut, _verdicts(cases)


@pytest.mark.impls(seconds=30)
def test_a_box_whose_latency_grows_through_the_stream_fails_t2(tmp_path: Path) -> None:
    case = _run("latency-grows", tmp_path, "T2-01")["T2-01"]
    assert case["verdict"] == "FAIL" and "backlog" in str(case["message"]), case


@pytest.mark.impls(seconds=40)
def test_a_robot_streaming_at_45_hz_still_fails_t2(tmp_path: Path) -> None:
    args = argparse.Namespace(time_out=0, limit=240, mem_limit=1024, base_seed=0)
    row = run_robot(EXPECTATIONS["stream-45hz"], args, tmp_path, 0, False)
    assert row.judgement in ("ok", "ok?") and row.totals.get("FAIL") and any("T2" in f for f in row.first), row

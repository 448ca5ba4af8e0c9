"""``run --lanes``: against a slow legal box (every answer 100 ms late, serving several connections),
auto picks lanes; the verdicts and their order are those of a run one case at a time, and no case that
runs alone (cycle state, timing) has another case beside it."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest
from scapy.utils import rdpcap

from tests.impls.box import start_box

pytestmark = pytest.mark.e2e
#: shared cases (frame, blocks, a garbage case, parse errors) and alone ones (cycle codes, S3, T1)
CASES = ["F1-*", "F2-*", "B1-*", "B2-02*", "A3-01*", "R2-01*", "A3-02", "S3-*", "T1-01"]
ALONE = ("A3-02", "S3-", "T1-")


def _run(port: int, lanes: str, out: Path) -> tuple[subprocess.CompletedProcess[str], dict]:
    args = [sys.executable, "-m", "conformance", "run", "--quiet", "--target", f"127.0.0.1:{port}", "--lanes", lanes,
            "--report-dir", str(out / "r"), "--pcap-dir", str(out / "p")]
    for glob in CASES:
        args += ["--cases", glob]
    proc = subprocess.run(args, capture_output=True, text=True, timeout=240)
    return proc, json.loads((out / "r" / "summary.json").read_text())


def _span(pcap: str) -> tuple[float, float] | None:
    times = [float(p.time) for p in rdpcap(pcap)]
    return (min(times), max(times)) if times else None  # a case that sent nothing (the baseline, answered before)


def test_lanes_on_a_slow_box_keep_the_serial_verdicts_and_run_the_alone_cases_alone(tmp_path: Path) -> None:
    box = start_box("late-inside-timeout")
    try:
        serial, serial_doc = _run(box.port, "1", tmp_path / "serial")
        laned, laned_doc = _run(box.port, "auto", tmp_path / "lanes")
    finally:
        box.stop()
    assert serial.returncode == 0 and laned.returncode == 0, laned.stderr[-2000:]
    assert "3 lanes" in laned.stderr and "serves two connections at once" in laned.stderr
    assert "lanes" not in serial.stderr
    assert serial_doc["suite"]["lanes"] == 1 and laned_doc["suite"]["lanes"] == 3  # the report says how it ran
    assert "3 lanes: the cases that share the box ran side by side" in (tmp_path / "lanes/r/report.html").read_text()
    one, three = serial_doc["cases"], laned_doc["cases"]
    assert [(c["id"], c["verdict"]) for c in three] == [(c["id"], c["verdict"]) for c in one]
    assert len(three) >= 20
    found = {c["id"]: _span(c["pcap"]) for c in three if c["pcap"] and Path(c["pcap"]).exists()}
    spans = {case_id: span for case_id, span in found.items() if span is not None}
    alone = [i for i in spans if i.startswith(ALONE)]
    shared = [i for i in spans if not i.startswith(ALONE) and i != "T1-00"]
    assert alone and shared
    for a in alone:
        for s in shared:
            (a0, a1), (s0, s1) = spans[a], spans[s]
            assert a1 < s0 or s1 < a0, f"{a} ran beside {s}"
    starts = sorted(spans[s][0] for s in shared)
    ends = sorted(spans[s][1] for s in shared)
    assert any(s < e for s, e in zip(starts[1:], ends[:-1])), "no two shared cases ran side by side"

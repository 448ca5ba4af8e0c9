"""The vendor's view end to end (issue 34): ``isight-conformance run`` against boxes of tests/impls served as their
own processes (``python -m tests.impls.box NAME``), reading summary.json's first root cause.

* A box that reads UDP another way than PROTOCOL.md: the first root cause names the mechanism (the CRC it uses and
  the flag to rerun with), and every UDP FAIL belongs to it. The UDP and F6 cases only, so each run is short.
* A box whose whole loop stalls once for 6 s during FUZZ-01: reported as a box stall (T1/S4: when, how long, who),
  never as NON-STRICT R6 of the bytes in flight.
* A legal box that completes a 12-byte header with the probe's first two bytes: FUZZ-01 comes out clean."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest

ROOT = Path(__file__).resolve().parents[2]
ENV = {**os.environ, "PYTHONPATH": str(ROOT)}
TRANSPORT_CASES = ["--cases", "F6-*", "--cases", "F7-*", "--cases", "R7-*"]


def run_against(box: str, tmp_path: Path, *cases: str) -> tuple[int, dict[str, Any]]:
    proc = subprocess.Popen([sys.executable, "-m", "tests.impls.box", box, "--port", "0"], stdout=subprocess.PIPE,
                            text=True, cwd=ROOT, env=ENV)
    try:
        assert proc.stdout is not None
        words = proc.stdout.readline().split()
        flags = ["--target", words[2]] + (["--udp-target", words[4]] if "udp" in words else [])
        flags += words[words.index("args") + 1:] if "args" in words else []
        report = tmp_path / "report"
        done = subprocess.run([sys.executable, "-m", "conformance", "run", *flags, "--quiet", "--capture", "off",
                               "--report-dir", str(report), *cases], capture_output=True, text=True, timeout=400,
                              cwd=tmp_path, env=ENV)
    finally:
        proc.terminate()
        proc.wait(10)
    return done.returncode, json.loads((report / "summary.json").read_text())


@pytest.mark.impls(seconds=40)
@pytest.mark.parametrize("box, words", [
    ("udp-crc-ccitt", "Signs and checks UDP frames with CRC-16/CCITT-FALSE, not CRC-16/MODBUS: rerun with "
                      "`--crc crc-ccitt-false`"),
    ("udp-answer-port", "Sends its UDP answers to the request's source port +1"),
    ("tcp-check-crc", "in the check field of its TCP answers"),
])
def test_the_first_root_cause_names_the_transport_mechanism(box: str, words: str, tmp_path: Path) -> None:
    code, doc = run_against(box, tmp_path, *TRANSPORT_CASES)
    assert code == 1
    first = doc["root_causes"][0]
    assert words in first["title"] and first["confirmed"] is True, first["title"]
    failing = {c["id"] for c in doc["cases"] if c["verdict"] == "FAIL"}
    assert failing and failing <= set(first["cases"]), (failing, first["cases"])


@pytest.mark.impls(seconds=40)
def test_a_box_stall_during_fuzzing_is_a_stall_not_an_r6(tmp_path: Path) -> None:
    code, doc = run_against("stall-once", tmp_path, "--cases", "FUZZ-01")
    assert code == 1
    first = doc["root_causes"][0]
    assert first["clauses"][:2] == ["T1", "S4"] and "stalled for about 6" in first["title"], first["title"]
    assert not any(c["verdict"] == "NON-STRICT" for c in doc["cases"])


@pytest.mark.impls(seconds=40)
def test_a_legal_box_completing_a_short_frame_with_the_probe_comes_out_clean(tmp_path: Path) -> None:
    code, doc = run_against("completes-short", tmp_path, "--cases", "FUZZ-01")
    assert code == 0, [(c["id"], c["message"]) for c in doc["cases"] if c["verdict"] != "PASS"]

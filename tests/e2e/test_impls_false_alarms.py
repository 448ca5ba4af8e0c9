"""Each false alarm the sampled legal combinations found (python -m tests.impls.matrix --sample), kept fixed.

Every test starts an independent box with the knob values that exposed the false alarm (in this
process, loopback) and runs the real suite (``isight-conformance run --cases ...``) against it: the
cases that once FAILed or went NON-STRICT on a conforming box must now PASS (or be another clean
verdict). A few seconds each.
"""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

import pytest

from tests.impls import boxcore
from tests.impls.boxcore import ThreadBox
from tests.impls.matrix import suite_command
from tests.impls.policy import knob_choices

CLEAN = {"PASS", "INFORMATIONAL", "INCONCLUSIVE", "SKIP"}


def verdicts(knobs: dict[str, str], cases: str, tmp_path: Path, *flags: str) -> dict[str, str]:
    """The verdicts of the cases matching ``cases`` (globs, comma-separated) against a box with ``knobs``."""
    choices = knob_choices(knobs)
    selected = [arg for glob in cases.split(",") for arg in ("--cases", glob)]
    with ThreadBox(choices).start() as box:
        cmd = [*suite_command(), "run", "--target", f"127.0.0.1:{box.port}", "--quiet", *selected,
               "--report-dir", str(tmp_path / "report"), "--pcap-dir", str(tmp_path / "pcaps"), *choices.suite_args(),
               *flags]
        done = subprocess.run(cmd, capture_output=True, text=True, timeout=180)
    assert done.returncode in (0, 1), done.stderr[-2000:]
    summary = json.loads((tmp_path / "report" / "summary.json").read_text())
    return {c["id"]: f"{c['verdict']}: {c['message']}" for c in summary["cases"]}


def unclean(result: dict[str, str]) -> dict[str, str]:
    return {k: v for k, v in result.items() if v.split(":", 1)[0] not in CLEAN}


@pytest.mark.parametrize("tcp_check", ["ignore", "zero-or-crc"])
def test_f6_02_sends_its_pose_from_the_profile_s_first_index(tcp_check: str, tmp_path: Path) -> None:
    """first_index=1 (--first-index 1): F6-02's pose carried index 00, so a box taking the CRC got NON-STRICT."""
    result = verdicts({"first_index": "1", "tcp_check": tcp_check}, "F6-02", tmp_path)
    assert result["F6-02"].startswith("PASS"), result


def test_a1_10_takes_a_progidx_409_in_the_error_field_under_error_code(tmp_path: Path) -> None:
    """prog_idx=409 progidx_conflict=error-code (--progidx-conflict error-code): A1-10 replayed the ProgIdx
    vectors expecting 409 in the block, and FAILed the answer E2-01 accepts."""
    result = verdicts({"prog_idx": "409", "progidx_conflict": "error-code"}, "A1-10*,E2-01", tmp_path)
    assert not unclean(result), unclean(result)
    assert result["E2-01"].startswith(("PASS", "INFORMATIONAL")) and len([k for k in result if k.startswith("A1-10")]) >= 3, result


def test_a_result_polled_busy_gets_a_full_vision_time_out_on_every_try(tmp_path: Path,
                                                                      monkeypatch: pytest.MonkeyPatch) -> None:
    """vision_result=202 latency=100ms (always busy, each answer late): E4-01's last retry waited only what was
    left of vision_time_out (6 ms) and FAILed the box for a silence the suite made. Here every answer takes
    0.3 s and vision_time_out is 1 s, so the third try (at 0.8 s) always had too little left."""
    monkeypatch.setitem(boxcore.LATENCY, "100ms", 0.3)
    result = verdicts({"vision_result": "202", "latency": "100ms"}, "E4-01", tmp_path, "--vision-time-out", "1000")
    assert result["E4-01"].split(":")[0] in CLEAN, result

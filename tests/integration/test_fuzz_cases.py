"""The fuzz cases of the suite (conformance/cases/fuzzing.py): PASS on the reference box, FAIL on broken ones."""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

import pytest

from tests.integration.test_fuzz_campaign import patched_box, zero_to_bad_pose_index
from tests.integration.test_fuzz_stateful import pose_error_during_a_cycle

pytestmark = pytest.mark.timeout(120)


def run_cases(tmp: Path, target: str | None) -> dict[str, dict[str, Any]]:
    args = ["-c", os.devnull, "--rootdir", str(tmp), "--pyargs", "conformance.cases", "-p", "no:cacheprovider",
            "-p", "no:terminal", "--cases", "FUZZ-*", "--report-dir", str(tmp / "report"), "--pcap-dir", str(tmp / "p")]
    if target:
        args += ["--target", target]
    assert pytest.main(args) in (0, 1)
    return {c["id"]: c for c in json.loads((tmp / "report" / "summary.json").read_text())["cases"]}


def test_the_fuzz_cases_pass_on_the_bundled_box(tmp_path: Path) -> None:
    cases = run_cases(tmp_path, None)
    assert {cid: c["verdict"] for cid, c in cases.items()} == {"T1-00": "PASS", "FUZZ-01": "PASS", "FUZZ-02": "PASS"}
    assert Path(cases["FUZZ-01"]["pcap"]).stat().st_size > 10_000


def test_the_fuzz_cases_fail_on_broken_boxes_with_the_shrunk_bytes(tmp_path: Path) -> None:
    with patched_box(zero_to_bad_pose_index, pose_error_during_a_cycle) as box:
        cases = run_cases(tmp_path, f"127.0.0.1:{box.tcp_port}")
    frames, sessions = cases["FUZZ-01"], cases["FUZZ-02"]
    assert frames["verdict"] == "FAIL" and sessions["verdict"] == "FAIL"
    # either planted defect may come first (the frames send CycleOn too, and poses in a cycle get 1001)
    assert "MUST NOT be answered 0000" in frames["message"] or "is answered 0000" in frames["message"]
    assert frames["sent_hex"].replace(" ", "").startswith("fefe0001012301")
    assert "vector" in frames["observed"]
    assert (tmp_path / "report" / "fuzz" / "FUZZ-01-failure-001.json").is_file()
    assert (tmp_path / "p" / "FUZZ-01-failure-001.pcapng").is_file()

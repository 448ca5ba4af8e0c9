"""The cases under pytest-xdist (conformance/xdist_hooks.py): the same complete reports as a serial run,
one box's cases on one worker in catalogue order, only the controller writing reports."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

pytest.importorskip("xdist", reason="pytest-xdist is not installed (pip install 'isight-conformance[xdist]')")

from conformance.endpoints.bundled import start_bundled  # noqa: E402
from conformance.protocol import Profile  # noqa: E402

CASES = ("--cases", "A4-*", "--cases", "F1-*", "--cases", "A2-*", "--cases", "S2-01")


def pytest_run(tmp_path: Path, *args: str) -> subprocess.CompletedProcess[str]:
    cmd = [sys.executable, "-m", "pytest", "--pyargs", "conformance.cases", "-p", "no:cacheprovider", "-q",
           "--isight-capture", "off", *CASES, *args]
    return subprocess.run(cmd, capture_output=True, text=True, timeout=300, cwd=tmp_path)


def summary(path: Path) -> dict:
    return json.loads((path / "summary.json").read_text())


def test_n2_gives_the_same_complete_report_as_a_serial_run(tmp_path: Path) -> None:
    serial = pytest_run(tmp_path, "--report-dir", str(tmp_path / "serial"))
    assert serial.returncode == 0, serial.stdout + serial.stderr
    parallel = pytest_run(tmp_path, "-n", "2", "--report-dir", str(tmp_path / "xdist"))
    assert parallel.returncode == 0, parallel.stdout + parallel.stderr
    one, two = summary(tmp_path / "serial"), summary(tmp_path / "xdist")
    assert [c["id"] for c in two["cases"]] == [c["id"] for c in one["cases"]]  # complete, in catalogue order
    assert two["totals"] == one["totals"] and two["suite"]["complete"] is True
    assert two["suite"]["target"].startswith("bundled reference box at 127.0.0.1:")
    # only the controller wrote: one report, no per-worker directories or partial summaries
    assert sorted(p.name for p in (tmp_path / "xdist").iterdir()) == ["junit.xml", "report.html", "summary.json"]


def test_several_targets_give_one_report_each_with_each_box_on_one_worker(tmp_path: Path) -> None:
    boxes = [start_bundled(Profile()), start_bundled(Profile())]
    try:
        proc = pytest_run(tmp_path, "-n", "2", "--report-dir", str(tmp_path / "r"), "-vv",  # one line per case
                          *[arg for box in boxes for arg in ("--target", str(box.target))])
    finally:
        for box in boxes:
            box.stop()
    assert proc.returncode == 0, proc.stdout + proc.stderr
    orders = []
    for box in boxes:
        doc = summary(tmp_path / "r" / str(box.target).replace(":", "_"))
        assert doc["suite"]["target"] == str(box.target) and doc["suite"]["complete"] is True
        ids = [c["id"] for c in doc["cases"]]
        assert all("127.0.0.1" not in i for i in ids)  # the box is not part of a case's ID
        orders.append(ids)
        workers = {line.split()[0] for line in proc.stdout.splitlines()
                   if line.startswith("[gw") and f"{box.target}]" in line}
        assert len(workers) == 1, workers  # one box's cases on one worker: its cycle state is shared
    assert orders[0] == orders[1] and orders[0][0] == "T1-00"


def test_a_cases_box_is_read_from_its_node_id() -> None:
    from conformance.xdist_hooks import box_key

    keys = ["127.0.0.1:9004", "127.0.0.1:19004"]
    assert box_key("actions.py::test_answer_shape[pose-127.0.0.1:19004]", keys) == "127.0.0.1:19004"
    assert box_key("baseline.py::test_baseline[127.0.0.1:9004]", keys) == "127.0.0.1:9004"
    assert box_key("baseline.py::test_baseline", keys) == ""  # one box: one scope
    assert box_key("actions.py::test_answer_shape[pose]", []) == ""

"""``isight-conformance monitor`` as a process: checkpoints while it runs, SIGTERM mid-session leaves
complete reports and a ring of pcapng files each readable on its own (about 3 s)."""

from __future__ import annotations

import json
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from conformance.analyze import AnalyzeConfig, analyze
from conformance.analyze.capture import CaptureReader
from conformance.endpoints.bundled import start_bundled
from conformance.endpoints.robot import RobotSession, run_robot
from conformance.protocol import DEFAULT_PROFILE

WAIT = 30.0


def _until(what, timeout: float = WAIT):  # type: ignore[no-untyped-def]
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        got = what()
        if got:
            return got
        time.sleep(0.05)
    raise AssertionError("timed out")


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGHUP])
def test_a_signal_mid_session_leaves_whole_reports_and_readable_pcaps(tmp_path: Path, sig: int) -> None:
    box = start_bundled(DEFAULT_PROFILE)
    reports, pcaps = tmp_path / "report", tmp_path / "pcaps"
    proc = subprocess.Popen(
        [sys.executable, "-m", "conformance", "monitor", "--listen", "127.0.0.1:0", "--upstream", str(box.target),
         "--report-dir", str(reports), "--pcap-dir", str(pcaps), "--ring", "3", "--ring-mb", "0.005",
         "--checkpoint", "0.01", "--quiet"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        assert proc.stdout is not None
        first = proc.stdout.readline()
        assert first.startswith("listening tcp 127.0.0.1:"), first + (proc.stderr.read() if proc.poll() else "")
        port = int(first.split()[2].rsplit(":", 1)[1])
        results = []
        robot = threading.Thread(target=lambda: results.append(
            run_robot(RobotSession(("127.0.0.1", port), DEFAULT_PROFILE, duration=20))))
        robot.start()
        _until(lambda: (reports / "summary.json").exists())  # a checkpoint, while the session runs
        _until(lambda: len(list(pcaps.glob("*.pcapng"))) >= 2)  # the ring has turned
        proc.send_signal(sig)
        out, err = proc.communicate(timeout=WAIT)
        robot.join(WAIT)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
        box.stop()
    assert proc.returncode in (0, 1), err
    assert results and results[0].exit_code == 5  # the robot saw its connections close
    summary = json.loads((reports / "summary.json").read_text())
    doc = json.loads((reports / "monitor.json").read_text())
    assert doc["connections"] == 2 and doc["packets"] > 0
    assert {c["id"] for c in summary["cases"]} >= {"OBS-S1-robot", "OBS-T1-box"}
    assert (reports / "junit.xml").read_text().rstrip().endswith("</testsuites>")
    assert (reports / "report.html").read_text().rstrip().endswith("</html>")
    files = sorted(pcaps.glob("*.pcapng"))
    assert 1 <= len(files) <= 3 and [f.name for f in files] == [e["file"] for e in doc["ring"]]
    for path in files:
        reader = CaptureReader(path)
        frames = sum(1 for _ in reader.packets())
        reader.close()
        assert reader.truncated is None and frames > 0
        assert analyze(path, AnalyzeConfig(ports=(box.target.port,), heuristic=False)).found
    assert not list(tmp_path.glob("*/*.tmp*"))  # atomic writes leave no temporary files


def test_a_bad_fault_spec_or_address_is_one_line_and_exit_2(tmp_path: Path) -> None:
    for extra in (["--fault", "drop:BOGUS"], ["--ring", "0"], ["--upstream", "nohost"]):
        args = ["--listen", "127.0.0.1:0", "--upstream", "127.0.0.1:9", "--report-dir", str(tmp_path / "r"),
                "--no-pcap", *extra]
        proc = subprocess.run([sys.executable, "-m", "conformance", "monitor", *args], capture_output=True,
                              text=True, timeout=WAIT)
        assert proc.returncode == 2, proc.stderr
        assert len(proc.stderr.strip().splitlines()) == 1 and "Traceback" not in proc.stderr

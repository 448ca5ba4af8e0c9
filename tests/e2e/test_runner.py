"""conformance.commands.run and run_flow: ``isight-conformance run`` end to end (subprocesses, loopback, bounded)."""

from __future__ import annotations

import json
import re
import socket
import subprocess
import sys
import time
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

from conformance.protocol import ErrorCode, answer, encode
from tests.boxes import ScriptedBox, answering, close_at_once, silent

pytestmark = pytest.mark.timeout(240)


def run(tmp_path: Path, *args: str, timeout: float = 200) -> tuple[subprocess.CompletedProcess[str], float]:
    start = time.monotonic()
    proc = subprocess.run(
        [sys.executable, "-m", "conformance", "run", "--quiet", "--report-dir", str(tmp_path / "r"),
         "--pcap-dir", str(tmp_path / "p"), *args],
        capture_output=True, text=True, timeout=timeout, cwd=tmp_path,
    )
    return proc, time.monotonic() - start


def summary(tmp_path: Path) -> dict:
    return json.loads((tmp_path / "r" / "summary.json").read_text())


def test_bundled_box_conforms_with_every_report_and_a_pcap_per_case(tmp_path: Path) -> None:
    proc, _ = run(tmp_path, "--cases", "F*")
    assert proc.returncode == 0, proc.stdout + proc.stderr
    doc = summary(tmp_path)
    assert set(doc) == {"suite", "root_causes", "cases", "totals", "acceptance"}
    assert doc["root_causes"] == [] and doc["suite"]["complete"] is True
    assert {"version", "started", "duration_s", "target", "profile"} <= set(doc["suite"])
    assert doc["suite"]["target"].startswith("bundled reference box at 127.0.0.1:")
    assert doc["totals"]["FAIL"] == doc["totals"]["ERROR"] == 0 and doc["totals"]["PASS"] >= 5
    for case in doc["cases"]:
        assert {"id", "clauses", "level", "verdict", "duration_s", "message", "pcap"} <= set(case)
        assert (tmp_path / case["pcap"]).is_file(), case
    root = ET.parse(tmp_path / "r" / "junit.xml").getroot()
    cases = root.iter("testcase")
    assert all(c.get("name") and c.get("classname") for c in cases)
    html = (tmp_path / "r" / "report.html").read_text()
    assert "F1-01" in html and "CONFORMS" in html


def test_unreachable_target_is_one_line_and_exit_2(tmp_path: Path) -> None:
    import socket

    with socket.socket() as holder:
        holder.bind(("127.0.0.1", 0))
        proc, took = run(tmp_path, "--target", f"127.0.0.1:{holder.getsockname()[1]}", "--time-out", "1000")
    assert proc.returncode == 2
    assert proc.stderr.strip().count("\n") == 0 and "refused" in proc.stderr
    assert "Traceback" not in proc.stderr + proc.stdout


def test_usage_errors_exit_2_without_traceback(tmp_path: Path) -> None:
    for args in (["--target", "box:0"], ["--stream-seconds", "0"], ["--expected-failures", str(tmp_path / "nope.txt")]):
        proc, _ = run(tmp_path, *args)
        assert proc.returncode == 2, args
        assert "Traceback" not in proc.stderr


def test_an_unreachable_target_exits_2_and_leaves_no_run_directories(tmp_path: Path) -> None:
    with socket.socket() as sock:  # a port nothing listens on (bound, never listening: connections refused)
        sock.bind(("127.0.0.1", 0))
        port = sock.getsockname()[1]
        proc = subprocess.run([sys.executable, "-m", "conformance", "run", "--quiet", "--target", f"127.0.0.1:{port}"],
                              capture_output=True, text=True, timeout=60, cwd=tmp_path)
    assert proc.returncode == 2 and "unreachable" in proc.stderr, proc.stderr
    assert not (tmp_path / "reports").exists() and not (tmp_path / "pcaps").exists()


def test_box_that_accepts_and_never_answers_ends_with_clear_verdicts(tmp_path: Path) -> None:
    with ScriptedBox(silent) as box:
        proc, took = run(tmp_path, "--target", box.target, "--time-out", "300", "--cases", "F*")
    assert proc.returncode == 1, proc.stdout + proc.stderr
    verdicts = {c["id"]: c["verdict"] for c in summary(tmp_path)["cases"]}
    assert "FAIL" in verdicts.values()
    assert set(verdicts.values()) <= {"FAIL", "INCONCLUSIVE", "NON-STRICT", "PASS"}
    assert took < 60


def test_box_that_closes_at_once_fails_cleanly(tmp_path: Path) -> None:
    with ScriptedBox(close_at_once) as box:
        proc, _ = run(tmp_path, "--target", box.target, "--time-out", "500", "--cases", "F*")
    assert proc.returncode == 1
    assert "Traceback" not in proc.stdout + proc.stderr
    assert summary(tmp_path)["totals"]["ERROR"] == 0


def test_expected_failures_list_gates_the_exit_code(tmp_path: Path) -> None:
    # a box that answers everything 0000, even a wrong version: A5 cases fail
    with ScriptedBox(answering(lambda f: encode(answer(f.action, ErrorCode.OK)))) as box:
        # F1-F7 only: FUZZ-01/02 (also "F*") fuzz for a fixed wall time, so what they find varies with load
        proc, _ = run(tmp_path, "--target", box.target, "--cases", "F[1-7]-*")
        assert proc.returncode in (0, 1)
        failing = sorted(c["id"] for c in summary(tmp_path)["cases"] if c["verdict"] in ("FAIL", "ERROR"))
        listed = tmp_path / "expected.txt"
        listed.write_text("# known failures\n" + "".join(f"{i}  # why\n" for i in failing))
        proc, _ = run(tmp_path, "--target", box.target, "--cases", "F[1-7]-*", "--expected-failures", str(listed))
        assert proc.returncode == 0, proc.stderr
        assert (tmp_path / "r" / "failing_cases.txt").read_text().split() == failing
        listed.write_text("F1-01\n")
        proc, _ = run(tmp_path, "--target", box.target, "--cases", "F[1-7]-*", "--expected-failures", str(listed))
    assert proc.returncode == 1
    assert "F1-01" in (tmp_path / "r" / "unexpectedly_passing.txt").read_text()
    assert "differs from the expected-failures list" in proc.stderr


def test_list_prints_the_catalogue(tmp_path: Path) -> None:
    proc = subprocess.run([sys.executable, "-m", "conformance", "run", "--list"], capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0
    assert "F1-01" in proc.stdout and proc.stdout.strip().endswith("cases")


def test_catalogue_doc_is_generated_from_the_cases() -> None:
    """docs/CATALOGUE.md must be what `run --list --list-format markdown` prints today."""
    root = Path(__file__).resolve().parents[2]
    proc = subprocess.run([sys.executable, "-m", "conformance", "run", "--list", "--list-format", "markdown"],
                          capture_output=True, text=True, timeout=60, cwd=root)
    assert proc.returncode == 0, proc.stderr
    doc = (root / "docs" / "CATALOGUE.md").read_text(encoding="utf-8")
    assert doc == proc.stdout, "docs/CATALOGUE.md is stale: regenerate it with " \
        "`isight-conformance run --list --list-format markdown > docs/CATALOGUE.md`"


def test_a_log_holds_the_summary_and_verbose_every_row(tmp_path: Path) -> None:
    """Without a TTY (a pipe, as in CI) the output is the final summary: no row per INFORMATIONAL, SKIP
    or PASS case, no clause text; --verbose prints a row per case as it finishes."""
    cases = ["--cases", "F1-*", "--cases", "B3-01", "--cases", "SEQ-USER*"]
    base = [sys.executable, "-m", "conformance", "run", "--report-dir", str(tmp_path / "r"), "--pcap-dir",
            str(tmp_path / "p"), *cases]
    plain = subprocess.run(base, capture_output=True, text=True, timeout=200, cwd=tmp_path)
    verbose = subprocess.run([*base, "--verbose"], capture_output=True, text=True, timeout=200, cwd=tmp_path)
    assert plain.returncode == verbose.returncode == 0, plain.stdout + plain.stderr + verbose.stderr
    rows = [line for line in plain.stdout.splitlines() if line.startswith(("PASS", "INFORMATIONAL", "SKIP"))]
    assert rows == [] and "B3-01" not in plain.stdout and "B3 (MUST)" not in plain.stdout, plain.stdout
    assert "Totals:" in plain.stdout and "INFORMATIONAL 1" in plain.stdout and "SKIP 1" in plain.stdout, plain.stdout
    out = verbose.stdout
    assert re.search(r"^INFORMATIONAL B3-01 \[B3\]", out, re.M) and re.search(r"^SKIP +SEQ-USER", out, re.M), out
    assert re.search(r"^PASS +F1-01", out, re.M) and "B3 (MUST)" in out and "Totals:" in out, out

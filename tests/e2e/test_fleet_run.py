"""``isight-conformance run --targets FILE`` end to end (conformance/commands/fleet.py, conformance/fleet/fleet_run.py): bundled boxes, a box with
a planted defect and its expected failures, a stop by signal, and the usage errors (exit 2, one line)."""

from __future__ import annotations

import json
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from conformance.commands import main
from tests.integration.test_fuzz_campaign import patched_box, zero_to_unknown_action

pytestmark = pytest.mark.timeout(240)


def fleet(tmp_path: Path, text: str, *args: str, timeout: float = 180) -> tuple[subprocess.CompletedProcess[str], dict]:
    tmp_path.mkdir(parents=True, exist_ok=True)
    path = tmp_path / "fleet.toml"
    path.write_text(text)
    out = tmp_path / "out"
    proc = subprocess.run([sys.executable, "-m", "conformance", "run", "--targets", str(path), "--report-dir", str(out),
                           "--quiet", *args], capture_output=True, text=True, timeout=timeout, cwd=tmp_path)
    doc = json.loads((out / "fleet.json").read_text()) if (out / "fleet.json").exists() else {}
    return proc, doc


def test_a_fleet_of_bundled_boxes_each_with_its_own_reports(tmp_path: Path) -> None:
    text = ('[defaults]\ncases = ["A4-*"]\n\n[[box]]\nname = "plain"\n\n'
            '[[box]]\nname = "index-one"\nfirst_index = 1\n\n[[box]]\nname = "lenient"\nchecking = "lenient"\n')
    proc, doc = fleet(tmp_path, text, "--jobs", "2")
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert doc["passed"] and doc["complete"] and doc["jobs"] == 2 and doc["exit_code"] == 0
    assert [b["name"] for b in doc["boxes"]] == ["plain", "index-one", "lenient"]
    out = tmp_path / "out"
    for box in doc["boxes"]:
        assert box["status"] == "conforms" and box["exit_code"] == 0, box
        summary = json.loads((out / box["summary"]).read_text())
        assert summary["totals"] == box["totals"] and box["totals"]["PASS"] >= 1
        ids = [c["id"] for c in summary["cases"]]
        assert "A4-01" in ids and not any(i.startswith(("F", "B", "R", "S")) for i in ids)  # --cases reached it
        assert (out / box["report"]).is_file() and (out / box["name"] / "junit.xml").is_file()
        assert list((out / box["name"] / "pcaps").glob("*.pcapng"))
        assert box["target"].startswith("bundled reference box at 127.0.0.1:")
    profiles = {b["name"]: json.loads((out / b["summary"]).read_text())["suite"]["profile"] for b in doc["boxes"]}
    assert profiles["index-one"]["first_index"] == 1 and profiles["plain"]["first_index"] == 0
    assert profiles["lenient"]["strict"] is False
    html = (out / "fleet.html").read_text()
    assert html.count('class="box"') == 3 and 'href="index-one/report.html"' in html
    assert "FLEET PASSES" in proc.stdout and "[3/3]" in proc.stdout
    # one package: the fleet directory and each box's directory verify on their own (issue 37)
    for package in (out, *(out / b["name"] for b in doc["boxes"])):
        assert main(["verify", str(package)]) == 0, package


def test_expected_failures_make_a_failing_box_pass_and_only_the_exact_set(tmp_path: Path) -> None:
    with patched_box(zero_to_unknown_action) as box:
        target = f"127.0.0.1:{box.tcp_port}"
        proc, doc = fleet(tmp_path / "1", f'[[box]]\nname = "planted"\ntarget = "{target}"\ncases = ["A5-*"]\n')
        assert proc.returncode == 1, proc.stdout + proc.stderr
        (first,) = doc["boxes"]
        failing = first["failing"]
        assert first["status"] == "fails" and failing and all(f.startswith("A5-") for f in failing)
        listed = ", ".join(f'"{f}"' for f in failing)
        text = (f'[defaults]\ntarget = "{target}"\ncases = ["A5-*"]\n\n'
                f'[[box]]\nname = "known"\nexpected_failures = [{listed}]\n\n'
                f'[[box]]\nname = "stale-list"\nexpected_failures = [{listed}, "A4-01"]\n')
        proc, doc = fleet(tmp_path / "2", text, "--jobs", "2")
    assert proc.returncode == 1, proc.stdout + proc.stderr
    known, stale = doc["boxes"]
    assert known["status"] == "expected failures" and known["passed"] and known["exit_code"] == 0
    assert known["failing"] == failing and known["unexpected_failures"] == []
    assert stale["status"] == "fails" and not stale["passed"]
    assert stale["unexpectedly_passing"] == ["A4-01"] and "expected to fail but did not: A4-01" in stale["message"]
    assert doc["overall"] == "FLEET FAILS: 1 of 2 boxes do not pass"


def _processes_mentioning(text: str) -> list[int]:
    pids = []
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                if text in (entry / "cmdline").read_bytes().decode("utf-8", "replace"):
                    state = (entry / "stat").read_text().rsplit(")", 1)[1].split()[0]
                    if state not in ("Z", "X"):
                        pids.append(int(entry.name))
            except (OSError, IndexError):
                continue
    return pids


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT], ids=["SIGTERM", "SIGINT"])
def test_a_signal_stops_every_child_and_fleet_json_covers_what_finished(tmp_path: Path, sig: signal.Signals) -> None:
    path = tmp_path / "fleet.toml"
    path.write_text('[[box]]\nname = "fast"\ncases = ["A4-*"]\n\n'
                    '[[box]]\nname = "slow"\ncases = ["T*"]\nstream_seconds = 60\n\n'
                    '[[box]]\nname = "later"\ncases = ["A4-*"]\n')
    out = tmp_path / "out"
    parent = subprocess.Popen([sys.executable, "-m", "conformance", "run", "--targets", str(path), "--report-dir",
                               str(out), "--quiet"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                              cwd=tmp_path)
    try:
        deadline = time.monotonic() + 120
        while not (out / "slow" / "run.log").exists() and time.monotonic() < deadline and parent.poll() is None:
            time.sleep(0.05)
        assert (out / "slow" / "run.log").exists(), "the second box never started"
        time.sleep(0.5)  # let it get going
        parent.send_signal(sig)
        stdout, stderr = parent.communicate(timeout=60)
    finally:
        if parent.poll() is None:
            parent.kill()
            parent.wait(timeout=10)
    assert parent.returncode == 1, stdout + stderr
    assert f"stopped by {sig.name}" in stderr
    doc = json.loads((out / "fleet.json").read_text())
    assert not doc["complete"] and not doc["passed"] and doc["stopped"] == f"stopped by {sig.name}"
    assert [(b["name"], b["status"]) for b in doc["boxes"]] == [("fast", "conforms"), ("slow", "interrupted"),
                                                                 ("later", "not run")]
    assert doc["boxes"][1]["exit_code"] is not None  # the child ended (and was reaped)
    assert not (out / "later").exists()
    assert _processes_mentioning(str(out)) == []  # no child or bundled box left behind
    assert (out / "fleet.html").is_file()


@pytest.mark.parametrize(("text", "args", "words"), [
    ('[[box]]\nname = "a"\n\n[[box]]\nname = "a"\n', (), "fleet.toml:5: duplicate box name 'a' (first at line 2)"),
    ('[[box]]\nname = "a"\ntarget = "10.0.0.5:x"\n', (), "fleet.toml:3: target = '10.0.0.5:x': bad target"),
    ('[[box]]\nname = "a"\nspeed = 3\n', (), "fleet.toml:3: unknown setting 'speed'"),
    ('[[box]\nname = "a"\n', (), "fleet.toml:1: not valid TOML"),
    ('[[box]]\nname = "a"\n', ("--target", "10.0.0.5:9004"), "--target does not go with --targets"),
    ('[[box]]\nname = "a"\n', ("--jobs", "0"), "--jobs must be at least 1"),
    ('[[box]]\nname = "a"\n', ("--expected-failures", "x.txt"), "--expected-failures does not go with --targets"),
])
def test_usage_errors_are_one_line_and_exit_2(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                              monkeypatch: pytest.MonkeyPatch, text: str, args: tuple[str, ...],
                                              words: str) -> None:
    monkeypatch.chdir(tmp_path)
    (tmp_path / "fleet.toml").write_text(text)
    assert main(["run", "--targets", "fleet.toml", *args]) == 2
    err = capsys.readouterr().err
    assert err.startswith("isight-conformance run: ") and words in err
    assert len(err.strip().splitlines()) == 1
    assert not (tmp_path / "reports").exists()  # nothing created for a fleet that never started


def test_a_missing_fleet_file(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["run", "--targets", str(tmp_path / "nope.toml")]) == 2
    assert "cannot read the fleet file" in capsys.readouterr().err
    assert not (tmp_path / "reports").exists()

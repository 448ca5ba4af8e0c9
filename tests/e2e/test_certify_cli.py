"""``isight-conformance certify-robot`` as a command: the listening line, exit codes, reports,
against the robot simulator run as another process (``python -m conformance robot``)."""

from __future__ import annotations

import json
import re
import subprocess
import sys
import time

import pytest

from conformance.commands import build_parser, main
from conformance.commands.certify_robot import DEFAULT_LISTEN
from conformance.commands.options import parse_listen

pytestmark = pytest.mark.timeout(60)

LISTENING = re.compile(r"^listening tcp 127\.0\.0\.1:(\d+) udp 127\.0\.0\.1:(\d+)$")


def _start(*args: str) -> tuple[subprocess.Popen, int]:
    proc = subprocess.Popen([sys.executable, "-m", "conformance", "certify-robot", "--listen", "127.0.0.1:0", *args],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    assert proc.stdout is not None
    first = proc.stdout.readline().strip()
    m = LISTENING.match(first)
    assert m, f"first line {first!r}; stderr: {proc.stderr.read() if proc.stderr else ''}"
    assert m.group(1) == m.group(2)  # one port for TCP and UDP
    return proc, int(m.group(1))


def test_certify_the_simulator_as_a_subprocess(tmp_path):
    proc, port = _start("--wait", "20", "--report-dir", str(tmp_path / "r"), "--pcap-dir", str(tmp_path / "p"),
                        "--rate-tolerance", "50", "--jitter-tolerance", "300")
    robot = subprocess.run([sys.executable, "-m", "conformance", "robot", "--target", f"127.0.0.1:{port}",
                            "--duration", "0.4", "-q"], capture_output=True, text=True, timeout=30)
    assert robot.returncode == 0, robot.stdout + robot.stderr
    out, err = proc.communicate(timeout=30)
    assert proc.returncode == 0, out + err
    assert "session 1: connection 1 accepted" in out and "session 1: ended" in out
    assert "CONFORMS (no FAIL/ERROR)" in out
    summary = json.loads((tmp_path / "r" / "summary.json").read_text())
    assert summary["totals"]["FAIL"] == summary["totals"]["ERROR"] == summary["totals"]["NON-STRICT"] == 0
    assert summary["suite"]["target"].startswith("robot at 127.0.0.1:")
    assert "certify-robot" in summary["suite"]["command"]
    assert {c["id"] for c in summary["cases"]} >= {"RB-S1-01", "RB-A1-01", "RB-T2-01", "RB-T2-02", "RB-S5-01"}
    assert (tmp_path / "r" / "junit.xml").exists() and (tmp_path / "r" / "report.html").exists()
    assert (tmp_path / "p" / "session-1.pcapng").exists()


def test_a_failing_robot_is_exit_1(tmp_path):
    # the suite expects indexes from 1; the simulator, with its default profile, sends them from 0 (B3)
    proc, port = _start("--wait", "20", "--quiet", "--report-dir", str(tmp_path / "r"), "--pcap-dir", str(tmp_path / "p"),
                        "--first-index", "1")
    robot = subprocess.run([sys.executable, "-m", "conformance", "robot", "--target", f"127.0.0.1:{port}",
                            "--duration", "0.3", "-q"], capture_output=True, text=True, timeout=30)
    out, err = proc.communicate(timeout=30)
    assert robot.returncode == 1
    assert proc.returncode == 1, out + err
    assert "RB-B3-01" in out and "session 1: connection" not in out  # --quiet: no event lines
    assert "DOES NOT CONFORM" in out


def test_no_robot_within_wait_is_exit_2_quickly(tmp_path):
    t = time.monotonic()
    proc = subprocess.run([sys.executable, "-m", "conformance", "certify-robot", "--listen", "127.0.0.1:0", "--wait", "1"],
                          capture_output=True, text=True, timeout=30, cwd=tmp_path)
    assert proc.returncode == 2
    assert [p.name for p in tmp_path.glob("*/*")] == []  # nothing judged, nothing written: no empty run directories
    assert LISTENING.match(proc.stdout.splitlines()[0])
    assert "no robot connected within --wait 1 s" in proc.stderr
    assert "Traceback" not in proc.stderr
    assert time.monotonic() - t < 20


@pytest.mark.parametrize("argv", [
    ["--listen", "nonsense"],
    ["--listen", "127.0.0.1:70000"],
    ["--sessions", "0"],
    ["--wait", "-1"],
    ["--rate-tolerance", "150"],
    ["--pose-rate", "0"],
    ["--answer-latency", "soon"],
    ["--answer-latency", "400-100"],
    ["--answer-latency", "100-5000"],  # not below time_out: the suite itself would break T1
])
def test_usage_errors_are_exit_2(argv, capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert main(["certify-robot", *argv]) == 2
    err = capsys.readouterr().err
    assert err.startswith("isight-conformance certify-robot:") and "Traceback" not in err
    assert list(tmp_path.rglob("*")) == []  # refused before any report or pcap directory was made


def test_unknown_injection_is_an_argparse_error(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["certify-robot", "--inject", "explode"])
    assert exc.value.code == 2
    assert "invalid choice" in capsys.readouterr().err


def test_cannot_listen_is_exit_2(capsys, tmp_path, monkeypatch):
    import socket

    monkeypatch.chdir(tmp_path)
    with socket.socket() as busy:
        busy.bind(("127.0.0.1", 0))
        busy.listen()
        port = busy.getsockname()[1]
        assert main(["certify-robot", "--listen", f"127.0.0.1:{port}", "--wait", "1"]) == 2
    assert "cannot listen" in capsys.readouterr().err
    assert [p.name for p in tmp_path.glob("*/*")] == []  # the run directories it made are gone again


def test_help_lists_the_flags():
    parser = build_parser()
    sub = next(a for a in parser._actions if a.dest == "command")
    text = sub.choices["certify-robot"].format_help()  # type: ignore[attr-defined]
    for flag in ("--listen", "--report-dir", "--pcap-dir", "--pose-rate", "--sessions", "--wait", "--extension",
                 "--inject", "--quiet", "--first-index", "--crc", "--time-out", "--linger", "--answer-latency", "--seed"):
        assert flag in text
    assert "127.0.0.1:9004" in text and "0.0.0.0:9004" in text


@pytest.mark.parametrize("text, expected", [
    ("127.0.0.1:9004", ("127.0.0.1", 9004)),
    ("0.0.0.0:0", ("0.0.0.0", 0)),
    ("[::1]:9004", ("::1", 9004)),
    ("localhost:1", ("localhost", 1)),
])
def test_parse_listen(text, expected):
    assert parse_listen(text) == expected


@pytest.mark.parametrize("text", ["", "9004", "host", ":9004", "h:x", "h:-1", "[::1]", "a:b:c"])
def test_parse_listen_rejects(text):
    with pytest.raises(ValueError):
        parse_listen(text)


def test_default_is_loopback():
    assert DEFAULT_LISTEN == "127.0.0.1:9004"


@pytest.mark.parametrize(("argv", "forced"), [
    ([], None),  # auto (the default): each session is judged as the session the robot runs
    (["--extension"], True),  # the flag alone, as before: forced on
    (["--extension", "auto"], None),
    (["--extension", "on"], True),
    (["--extension", "off"], False),
])
def test_extension_is_auto_on_or_off_as_run_spells_it(argv, forced, tmp_path):
    from conformance.commands.certify_robot import config_from_args

    parser = build_parser()
    args = parser.parse_args(["certify-robot", "--report-dir", str(tmp_path / "r"), "--pcap-dir", str(tmp_path / "p"),
                              *argv])
    assert config_from_args(args).extension is forced


def test_a_bad_extension_mode_is_an_argparse_error(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["certify-robot", "--extension", "maybe"])
    assert exc.value.code == 2 and "invalid choice" in capsys.readouterr().err

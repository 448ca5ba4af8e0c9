"""``isight-conformance analyze`` (conformance/commands/analyze.py): exit status 0/1/2, one clear
line for a file that is not a whole capture, the reports, the flags."""

from __future__ import annotations

import json

import pytest

from conformance.commands import build_parser, main
from conformance.commands.analyze import config_from_args
from conformance.protocol import Action, answer, encode, request
from tests.analyze_util import Capture, canonical, exchange


@pytest.fixture()
def clean(tmp_path):
    cap = Capture()
    canonical(cap)
    return cap.write(tmp_path / "clean.pcapng")


def run(capsys, *args):
    code = main(["analyze", *map(str, args)])
    out, err = capsys.readouterr()
    return code, out, err


def test_a_clean_capture_exits_0_with_reports(capsys, tmp_path, clean):
    code, out, err = run(capsys, clean, "--report-dir", tmp_path / "r", "--jitter-tolerance", "300")
    assert code == 0, err
    assert "CONFORMS" in out and "report.html" in out
    doc = json.loads((tmp_path / "r" / "summary.json").read_text())
    assert doc["suite"]["role"] == "observed" and "clean.pcapng" in doc["suite"]["target"]
    assert (tmp_path / "r" / "junit.xml").exists() and (tmp_path / "r" / "report.html").exists()


def test_a_failing_capture_exits_1(capsys, tmp_path):
    cap = Capture()
    conn = cap.tcp(41000)
    exchange(conn, encode(request(Action.NONE)), encode(answer(Action.CYCLE_ON)))  # not echoed: A2
    conn.close()
    code, _out, err = run(capsys, cap.write(tmp_path / "bad.pcap", fmt="pcap"), "--report-dir", tmp_path / "r")
    assert code == 1 and "OBS-A2-box" in err


@pytest.mark.parametrize("content, words", [
    (b"", "empty"),
    (b"hello, this is not a capture\n", "not a pcap or pcapng capture"),
    (None, "cut short"),
])
def test_a_bad_file_is_one_line_and_exit_2(capsys, tmp_path, clean, content, words):
    path = tmp_path / "bad.pcapng"
    path.write_bytes(clean.read_bytes()[:-9] if content is None else content)
    code, out, err = run(capsys, path, "--report-dir", tmp_path / "r")
    assert code == 2 and words in err
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err
    assert not (tmp_path / "r").exists()


def test_a_truncated_capture_can_be_judged_up_to_the_cut(capsys, tmp_path, clean):
    path = tmp_path / "cut.pcapng"
    path.write_bytes(clean.read_bytes()[:-9])
    code, out, _err = run(capsys, path, "--accept-truncated", "--report-dir", tmp_path / "r")
    assert code in (0, 1)
    assert "cut short" in json.loads((tmp_path / "r" / "summary.json").read_text())["suite"]["target"]


def test_no_isight_traffic_is_exit_2(capsys, tmp_path):
    cap = Capture()
    for _ in range(3):
        cap.other()
    code, _out, err = run(capsys, cap.write(tmp_path / "web.pcapng"), "--report-dir", tmp_path / "r")
    assert code == 2 and "no iSight traffic" in err and "--port" in err


def test_flags_build_the_config():
    args = build_parser().parse_args(["analyze", "x.pcap", "--port", "7000", "--port", "7001", "--no-heuristic",
                                      "--time-out", "200", "--crc", "xmodem", "--rate-tolerance", "20",
                                      "--no-extension", "--linger", "2"])
    config = config_from_args(args)
    assert config.ports == (7000, 7001) and not config.heuristic and config.crc_stated
    assert config.profile.time_out_ms == 200 and config.rate_tolerance == 0.2 and config.extension is False
    assert config.linger_s == 2
    assert config_from_args(build_parser().parse_args(["analyze", "x.pcap"])).crc_stated is False


def test_a_bad_flag_value_is_exit_2(capsys, clean):
    code, _out, err = run(capsys, clean, "--port", "70000")
    assert code == 2 and "--port" in err



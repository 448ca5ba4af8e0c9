"""The fuzz and replay commands (conformance/commands/fuzz.py and replay.py, conformance/fuzz/launch.py, via ``isight-conformance``): exit codes, the
planted-defect round trip (fuzz finds it, replay reproduces it, the reference box passes it)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from hypothesis import settings
from hypothesis.database import DirectoryBasedExampleDatabase

from conformance.commands import main
from conformance.evidence.vectors_file import REPO_VECTORS
from conformance.fuzz.database import DEFAULT_DATABASE, resolve_database
from tests.integration.test_fuzz_campaign import SHRUNK_BAD_INDEX, patched_box, zero_to_bad_pose_index

pytestmark = pytest.mark.timeout(120)


def test_an_unreachable_target_and_bad_files_are_usage_errors(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                                               monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)
    assert main(["fuzz", "--target", "127.0.0.1:1", "--max-examples", "5", "--report-dir", str(tmp_path)]) == 2
    assert "unreachable" in capsys.readouterr().err
    assert main(["replay", str(tmp_path / "missing.json"), "--target", "127.0.0.1:1"]) == 2
    with pytest.raises(SystemExit) as exc:
        main(["fuzz", "--max-examples", "5", "--duration", "1"])
    assert exc.value.code == 2
    assert main(["fuzz", "--max-examples", "5", "--categories", "nonsense", "--report-dir", str(tmp_path)]) == 2
    assert "unknown fuzz categories nonsense" in capsys.readouterr().err  # a usage error, not an internal one
    assert not (tmp_path / "pcaps").exists() and not (tmp_path / "reports").exists()  # refused before any was made


def test_fuzzing_the_bundled_box_prints_the_seed_and_writes_a_summary(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                                                     monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)
    code = main(["fuzz", "--max-examples", "300", "--seed", "5", "--report-dir", "r", "--quiet"])
    out = capsys.readouterr().out
    assert code == 0, out
    assert "seed 5 (rerun with: isight-conformance fuzz --seed 5)" in out  # the bundled box: no --target
    summary = json.loads((tmp_path / "r" / "fuzz-summary.json").read_text())
    assert summary["seed"] == 5 and summary["failures"] == [] and summary["examples"] == 240
    assert summary["database"] == str(DEFAULT_DATABASE) or summary["database"].startswith("off")


def test_the_planted_defect_round_trip(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Issue item 6: fuzz finds the defect (bounded, deterministic seed), shrunk to one frame, written;
    replay reproduces it against the broken box (1) and passes against the bundled box (0)."""
    with patched_box(zero_to_bad_pose_index) as box:
        target = f"127.0.0.1:{box.tcp_port}"
        code = main(["fuzz", "--target", target, "--max-examples", "3000", "--seed", "3", "--stateful-share", "0",
                     "--database", "none", "--report-dir", str(tmp_path / "r"), "--pcap-dir", str(tmp_path / "p"),
                     "--max-failures", "1", "--quiet"])
        out = capsys.readouterr().out
        assert code == 1, out
        vector = tmp_path / "r" / "fuzz-failure-001.json"
        doc = json.loads(vector.read_text())
        assert [t["hex"] for g in doc["testGroups"] for t in g["tests"]] == [SHRUNK_BAD_INDEX]
        assert (tmp_path / "p" / "fuzz-failure-001.pcapng").is_file()
        assert main(["replay", str(vector), "--target", target]) == 1
        assert "FAIL" in capsys.readouterr().out
    assert main(["replay", str(vector)]) == 0  # no --target: the bundled reference box
    assert "1 OK" in capsys.readouterr().out


def test_replaying_the_golden_vectors_against_the_bundled_box_passes(capsys: pytest.CaptureFixture[str]) -> None:
    files = [str(p) for p in sorted((REPO_VECTORS / "frames").glob("*.json"))]
    assert main(["replay", *files]) == 0
    out = capsys.readouterr().out
    assert "FAIL" not in out and "225 vectors" in out


def test_the_database_setting(tmp_path: Path) -> None:
    assert resolve_database("none")[0] is None
    db, label = resolve_database(str(tmp_path / "db"))
    assert isinstance(db, DirectoryBasedExampleDatabase) and label == str(tmp_path / "db")
    before = settings.get_current_profile_name()
    try:
        settings.load_profile("default")
        assert resolve_database(None)[1] == str(DEFAULT_DATABASE)
        settings.register_profile("no-db-for-test", database=None)
        settings.load_profile("no-db-for-test")
        db, label = resolve_database(None)
        assert db is None and "no-db-for-test" in label
    finally:
        settings.load_profile(before)


def test_restart_cmd_is_the_campaign_s_restart_and_the_report_prints_the_coverage(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch) -> None:
    import argparse
    import shlex
    import sys

    from conformance.commands.fuzz import add_arguments as add_fuzz_arguments
    from conformance.fuzz.launch import _restart

    parser = argparse.ArgumentParser()
    add_fuzz_arguments(parser)
    mark = tmp_path / "restarted"
    cmd = f"{shlex.quote(sys.executable)} -c \"open(r'{mark}', 'w').write('x')\""
    restart = _restart(parser.parse_args(["--restart-cmd", cmd]), None)
    assert restart is not None
    restart()
    assert mark.read_text() == "x"
    assert _restart(parser.parse_args([]), None) is None  # no box to restart: the campaign can only wait
    monkeypatch.chdir(tmp_path)
    assert main(["fuzz", "--max-examples", "200", "--seed", "5", "--report-dir", "r"]) == 0
    out = capsys.readouterr().out
    assert "fuzz: coverage: counts " in out and "state transitions " in out

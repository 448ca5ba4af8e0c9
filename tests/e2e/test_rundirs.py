"""Unique run directories (conformance/report/rundirs.py): runs started in the same second never share one."""

from __future__ import annotations

import multiprocessing
import os
import threading
from pathlib import Path

import pytest

from conformance.report import rundirs
from conformance.report.rundirs import default_run_dirs, drop_if_empty, unique_run_dirs

pytestmark = pytest.mark.timeout(60)


def test_the_first_run_gets_the_plain_stamp_and_the_next_ones_a_suffix(tmp_path: Path) -> None:
    first = unique_run_dirs("20240601-101500", tmp_path / "reports", tmp_path / "pcaps")
    second = unique_run_dirs("20240601-101500", tmp_path / "reports", tmp_path / "pcaps")
    third = unique_run_dirs("20240601-101500", tmp_path / "reports", tmp_path / "pcaps")
    assert [p.name for p in first] == ["20240601-101500"] * 2
    assert [p.name for p in second] == ["20240601-101500-2"] * 2
    assert [p.name for p in third] == ["20240601-101500-3"] * 2
    assert all(p.is_dir() for p in (*first, *second, *third))


def test_report_and_pcap_names_stay_paired_when_only_one_of_them_is_taken(tmp_path: Path) -> None:
    (tmp_path / "pcaps" / "S").mkdir(parents=True)  # left by an old run whose reports were deleted
    (tmp_path / "pcaps" / "S" / "keep.pcapng").write_bytes(b"x")
    reports, pcaps = unique_run_dirs("S", tmp_path / "reports", tmp_path / "pcaps")
    assert reports.name == pcaps.name == "S-2"
    assert not (tmp_path / "reports" / "S").exists()  # the name tried first was given back
    assert (tmp_path / "pcaps" / "S" / "keep.pcapng").read_bytes() == b"x"


def _create(args: tuple[str, str]) -> str:
    base, name = args
    (path,) = unique_run_dirs(name, base)
    return str(path)


def test_concurrent_creations_in_threads_never_share_a_directory(tmp_path: Path) -> None:
    n = 16
    barrier = threading.Barrier(n)
    got: list[Path] = []
    lock = threading.Lock()

    def worker() -> None:
        barrier.wait(timeout=20)
        paths = unique_run_dirs("same-second", tmp_path / "reports", tmp_path / "pcaps")
        with lock:
            got.extend(paths)

    threads = [threading.Thread(target=worker) for _ in range(n)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(timeout=30)
    reports = [p for p in got if p.parent.name == "reports"]
    pcaps = [p for p in got if p.parent.name == "pcaps"]
    assert len(reports) == len(pcaps) == n
    assert len(set(reports)) == n and len(set(pcaps)) == n
    assert sorted(p.name for p in reports) == sorted(p.name for p in pcaps)
    assert sorted(os.listdir(tmp_path / "reports")) == sorted(p.name for p in reports)


def test_two_processes_started_together_get_different_directories(tmp_path: Path) -> None:
    ctx = multiprocessing.get_context("fork")
    with ctx.Pool(2) as pool:
        paths = pool.map(_create, [(str(tmp_path / "reports"), "20240601-101500")] * 2)
    assert len(set(paths)) == 2
    assert sorted(Path(p).name for p in paths) == ["20240601-101500", "20240601-101500-2"]


def test_default_run_dirs_fills_in_only_what_is_missing(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(rundirs, "stamp", lambda now=None: "20240601-101500")
    a = default_run_dirs(None, None)
    b = default_run_dirs(None, None)
    assert a == (Path("reports/20240601-101500"), Path("pcaps/20240601-101500"))
    assert b == (Path("reports/20240601-101500-2"), Path("pcaps/20240601-101500-2"))
    assert default_run_dirs(None, None, pcaps=False) == (Path("reports/20240601-101500-3"), None)
    mine = tmp_path / "mine"
    # a report directory named on the line is one package: its pcaps go inside it
    assert default_run_dirs(mine, None, prefix="fuzz-") == (mine, mine / "pcaps")


def test_two_runs_in_the_same_second_write_separate_reports(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    from conformance.commands import main

    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(rundirs, "stamp", lambda now=None: "20240601-101500")
    for _ in range(2):
        assert main(["run", "--cases", "A4-*", "--quiet"]) == 0
    assert sorted(os.listdir(tmp_path / "reports")) == ["20240601-101500", "20240601-101500-2"]
    assert sorted(os.listdir(tmp_path / "pcaps")) == ["20240601-101500", "20240601-101500-2"]
    for name in ("20240601-101500", "20240601-101500-2"):
        assert (tmp_path / "reports" / name / "summary.json").is_file()


def test_drop_if_empty_removes_only_empty_run_directories(tmp_path: Path) -> None:
    empty, written = unique_run_dirs("S", tmp_path / "reports", tmp_path / "pcaps")
    (written / "case.pcapng").write_bytes(b"evidence")
    drop_if_empty(empty, written, None, tmp_path / "never-made")
    assert not empty.exists()
    assert (written / "case.pcapng").read_bytes() == b"evidence"  # evidence is never lost

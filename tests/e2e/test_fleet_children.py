"""The fleet's child processes (conformance/fleet/children.py): --jobs at a time, in file order, and a stop
that leaves no process behind. The children here are tiny Python scripts, not suite runs."""

from __future__ import annotations

import os
import signal
import sys
import threading
import time
from dataclasses import dataclass
from pathlib import Path

import pytest

from conformance.fleet.children import BoxRun, FleetRunner, stop_on_signals
from conformance.fleet.spec import BoxSpec

pytestmark = pytest.mark.timeout(120)


@dataclass
class ScriptRun(BoxRun):
    script: str = "pass"

    def child_command(self, quiet: bool = True) -> list[str]:
        return [sys.executable, "-c", self.script, str(self.report_dir)]


def runs(tmp_path: Path, scripts: list[str], expected: tuple[str, ...] | None = None) -> list[ScriptRun]:
    return [ScriptRun(BoxSpec(f"b{i}", i + 1, expected_failures=expected), tmp_path / f"b{i}", tmp_path / f"b{i}" / "p",
                      script=s) for i, s in enumerate(scripts)]


def alive(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except (OSError, IndexError):
        return False
    return state not in ("Z", "X")


def wait_for(predicate, seconds: float = 30.0) -> bool:  # type: ignore[no-untyped-def]
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        if predicate():
            return True
        time.sleep(0.02)
    return predicate()


def test_one_job_runs_the_boxes_one_after_the_other_in_file_order(tmp_path: Path) -> None:
    events: list[tuple[str, str]] = []
    boxes = runs(tmp_path, ["import sys; sys.exit(0)", "import sys; sys.exit(1)", "import sys; sys.exit(2)"])
    runner = FleetRunner(boxes, 1, on_start=lambda r: events.append(("start", r.name)),
                         on_done=lambda r: events.append(("done", r.name)))
    assert runner.run() is True and runner.stopped is None
    assert events == [("start", "b0"), ("done", "b0"), ("start", "b1"), ("done", "b1"), ("start", "b2"), ("done", "b2")]
    assert [b.exit_code for b in boxes] == [0, 1, 2]
    assert all(b.status == "finished" and b.duration_s is not None and b.log.is_file() for b in boxes)


def test_n_jobs_run_together_and_never_more(tmp_path: Path) -> None:
    go = tmp_path / "go"
    wait_go = ("import pathlib, sys, time\n"
               f"go = pathlib.Path({str(go)!r})\n"
               "deadline = time.monotonic() + 60\n"
               "while not go.exists() and time.monotonic() < deadline: time.sleep(0.02)\n"
               "sys.exit(0 if go.exists() else 3)\n")
    events: list[tuple[str, str]] = []

    def started(run: BoxRun) -> None:
        events.append(("start", run.name))
        if run.name == "b1":  # b0 can only finish once b1 runs beside it
            go.touch()

    boxes = runs(tmp_path, [wait_go, wait_go, "pass", "pass"])
    FleetRunner(boxes, 2, on_start=started, on_done=lambda r: events.append(("done", r.name))).run()
    assert [b.exit_code for b in boxes] == [0, 0, 0, 0]
    assert events[:2] == [("start", "b0"), ("start", "b1")]
    running, most = 0, 0
    for kind, _ in events:
        running += 1 if kind == "start" else -1
        most = max(most, running)
    assert most == 2
    assert [name for kind, name in events if kind == "start"] == ["b0", "b1", "b2", "b3"]


def test_two_boxes_with_the_same_target_never_run_at_the_same_time(tmp_path: Path) -> None:
    events: list[tuple[str, str]] = []
    boxes = runs(tmp_path, ["pass"] * 4)
    targets = ["10.0.0.5:9004", "10.0.0.5:9004", "10.0.0.6:9004", ""]
    for box, target in zip(boxes, targets):
        box.spec = BoxSpec(box.spec.name, box.spec.line, {"target": (target,)} if target else {})
    FleetRunner(boxes, 3, on_start=lambda r: events.append(("start", r.name)),
                on_done=lambda r: events.append(("done", r.name))).run()
    assert events.index(("done", "b0")) < events.index(("start", "b1"))  # same target: one after the other
    assert events[:3] == [("start", "b0"), ("start", "b2"), ("start", "b3")]  # the others did not wait
    assert all(b.exit_code == 0 for b in boxes)


def test_stale_results_are_removed_and_the_expected_failures_written(tmp_path: Path) -> None:
    (box,) = runs(tmp_path, ["pass"], expected=("T2-01", "R5-02"))
    box.report_dir.mkdir(parents=True)
    (box.report_dir / "summary.json").write_text('{"cases": []}')  # an earlier run's
    FleetRunner([box]).run()
    assert not (box.report_dir / "summary.json").exists()
    lines = box.expected_file.read_text().splitlines()
    assert lines[1:] == ["T2-01", "R5-02"] and lines[0].startswith("#")


def test_the_real_child_command_names_the_box_directories() -> None:
    spec = BoxSpec("cell-1", 3, {"target": ("10.0.0.5:9004",), "cases": ("A*", "F*")}, expected_failures=("T2-01",))
    run = BoxRun(spec, Path("out/cell-1"), Path("out/cell-1/pcaps"))
    cmd = run.child_command()
    assert cmd[:4] == [sys.executable, "-m", "conformance", "run"]
    assert cmd[4:] == ["--target=10.0.0.5:9004", "--cases=A*", "--cases=F*", "--report-dir", "out/cell-1",
                       "--pcap-dir", "out/cell-1/pcaps", "--lang", "en", "--expected-failures", "out/cell-1/expected_failures.txt",
                       "--quiet"]


GRANDPARENT = ("import pathlib, subprocess, sys, time\n"
               "d = pathlib.Path(sys.argv[1])\n"
               "g = subprocess.Popen(['sleep', '60'])\n"
               "(d / 'pids.tmp').write_text(f'{g.pid}')\n"
               "(d / 'pids.tmp').replace(d / 'pids')  # whole or absent: the test reads it once it exists\n"
               "time.sleep(60)\n")
STUBBORN = ("import pathlib, signal, sys, time\n"
            "signal.signal(signal.SIGINT, signal.SIG_IGN)\n"
            "d = pathlib.Path(sys.argv[1])\n"
            "(d / 'pids.tmp').write_text('x')\n"
            "(d / 'pids.tmp').replace(d / 'pids')\n"
            "time.sleep(60)\n")


@pytest.mark.parametrize("script", [GRANDPARENT, STUBBORN], ids=["with-a-grandchild", "ignores-sigint"])
def test_stop_ends_every_child_and_its_children_and_leaves_the_rest_not_run(tmp_path: Path, script: str) -> None:
    boxes = runs(tmp_path, [script, script, "pass"])
    runner = FleetRunner(boxes, 2, grace_s=2.0)
    thread = threading.Thread(target=runner.run)
    thread.start()
    try:
        assert wait_for(lambda: all((b.report_dir / "pids").exists() for b in boxes[:2]))
    finally:
        runner.stop("stopped by the test")
        thread.join(timeout=60)
    assert not thread.is_alive()
    assert runner.stopped == "stopped by the test"
    assert [b.status for b in boxes] == ["interrupted", "interrupted", "not run"]
    assert boxes[2].proc is None and boxes[2].exit_code is None
    for box in boxes[:2]:
        assert box.proc is not None and box.proc.returncode is not None
        assert not alive(box.proc.pid)
        if script is GRANDPARENT:
            grandchild = int((box.report_dir / "pids").read_text())
            assert wait_for(lambda pid=grandchild: not alive(pid), 10), f"grandchild {grandchild} survived"
        else:
            assert box.proc.returncode == -signal.SIGKILL  # SIGINT ignored: killed after the grace period


def test_signals_stop_the_runner_and_the_old_handlers_come_back(tmp_path: Path) -> None:
    before = signal.getsignal(signal.SIGTERM)
    runner = FleetRunner(runs(tmp_path, ["pass"]))
    with stop_on_signals(runner):
        os.kill(os.getpid(), signal.SIGTERM)
        assert wait_for(lambda: runner.stopped is not None, 5)
    assert runner.stopped == "stopped by SIGTERM"
    assert signal.getsignal(signal.SIGTERM) is before

"""Running a fleet: one ``isight-conformance run`` child process per box, at most ``jobs`` at once.

Each child runs in its own session (its own process group), writes its reports to
``DIR/<name>/`` and its output to ``DIR/<name>/run.log``. :meth:`FleetRunner.stop`
(called from a SIGINT/SIGTERM handler) ends the run: no new child starts, every
running child's process group gets SIGINT (what Ctrl-C does to a run: it writes the
reports of the cases that finished), and SIGKILL after ``grace_s`` if still alive.
"""

from __future__ import annotations

import contextlib
import os
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path

from ..i18n import current
from ..report.summary import atomic_write_bytes
from .spec import BoxSpec

#: how long stopped children get to write their reports before SIGKILL
STOP_GRACE_S = 15.0
POLL_S = 0.1


@dataclass
class BoxRun:
    """One box of a fleet run: where it writes, and what happened to it."""

    spec: BoxSpec
    report_dir: Path
    pcap_dir: Path
    status: str = "not run"  # "not run", "running", "finished", "interrupted"
    exit_code: int | None = None
    duration_s: float | None = None
    command: list[str] = field(default_factory=list)
    proc: subprocess.Popen[bytes] | None = None
    _started: float = 0.0

    @property
    def name(self) -> str:
        return self.spec.name

    @property
    def log(self) -> Path:
        return self.report_dir / "run.log"

    @property
    def expected_file(self) -> Path:
        return self.report_dir / "expected_failures.txt"

    def child_command(self, quiet: bool = True) -> list[str]:
        cmd = [sys.executable, "-m", "conformance", "run", *self.spec.flags(),
               "--report-dir", str(self.report_dir), "--pcap-dir", str(self.pcap_dir), "--lang", current()]
        if self.spec.expected_failures is not None:
            cmd += ["--expected-failures", str(self.expected_file)]
        if quiet:
            cmd.append("--quiet")
        return cmd


class FleetRunner:
    """Start the children ``jobs`` at a time, in file order (a box whose target is under test
    already waits its turn); wait; stop them all on request."""

    def __init__(self, boxes: Sequence[BoxRun], jobs: int = 1,
                 on_start: Callable[[BoxRun], None] = lambda run: None,
                 on_done: Callable[[BoxRun], None] = lambda run: None,
                 grace_s: float = STOP_GRACE_S) -> None:
        if jobs < 1:
            raise ValueError("--jobs must be at least 1")
        self.boxes = list(boxes)
        self.jobs = jobs
        self.on_start, self.on_done = on_start, on_done
        self.grace_s = grace_s
        self.stopped: str | None = None  # why the run was stopped, if it was
        self._wake = threading.Event()

    def stop(self, reason: str) -> None:
        """Ask the run to stop (safe from a signal handler): the loop stops the children."""
        if self.stopped is None:
            self.stopped = reason
        self._wake.set()

    def run(self) -> bool:
        """Run every box; True when all of them finished (False: stopped)."""
        pending = list(self.boxes)
        running: list[BoxRun] = []
        try:
            while (pending or running) and self.stopped is None:
                while len(running) < self.jobs and self.stopped is None:
                    box = _next(pending, running)
                    if box is None:
                        break
                    pending.remove(box)
                    self._start(box)
                    running.append(box)
                for box in list(running):
                    if box.proc is not None and box.proc.poll() is not None:
                        running.remove(box)
                        self._finish(box, "finished")
                self._wake.wait(POLL_S)
                self._wake.clear()
        except KeyboardInterrupt:
            self.stop("interrupted (Ctrl-C)")
        finally:
            if running:
                self._stop_children(running)
        return self.stopped is None

    # -- children -------------------------------------------------------------------------------
    def _start(self, box: BoxRun) -> None:
        box.report_dir.mkdir(parents=True, exist_ok=True)
        # a reused directory: the fleet must never read an older run's results as this one's
        for stale in ("summary.json", "failing_cases.txt", "unexpectedly_passing.txt"):
            with contextlib.suppress(FileNotFoundError):
                (box.report_dir / stale).unlink()
        if box.spec.expected_failures is not None:
            text = "".join(f"{case}\n" for case in box.spec.expected_failures)
            atomic_write_bytes(box.expected_file, f"# expected failures of box {box.name}\n{text}".encode())
        box.command = box.child_command()
        box._started = time.monotonic()
        box.status = "running"
        with open(box.log, "wb") as log:
            box.proc = subprocess.Popen(box.command, stdin=subprocess.DEVNULL, stdout=log, stderr=subprocess.STDOUT,
                                        start_new_session=True, env={**os.environ, "PYTHONUNBUFFERED": "1"})
        self.on_start(box)

    def _finish(self, box: BoxRun, status: str) -> None:
        assert box.proc is not None
        box.exit_code = box.proc.returncode
        box.duration_s = time.monotonic() - box._started
        box.status = status
        self.on_done(box)

    def _stop_children(self, running: list[BoxRun]) -> None:
        for box in running:
            _signal_group(box, signal.SIGINT)
        deadline = time.monotonic() + self.grace_s
        for box in running:
            assert box.proc is not None
            try:
                box.proc.wait(timeout=max(0.0, deadline - time.monotonic()))
            except subprocess.TimeoutExpired:
                _signal_group(box, signal.SIGKILL)
                with contextlib.suppress(subprocess.TimeoutExpired):
                    box.proc.wait(timeout=5)
            for_status = "interrupted"
            if box.proc.returncode is None:  # survived SIGKILL for 5 s: nothing more to do
                box.duration_s = time.monotonic() - box._started
                box.status = for_status
                continue
            self._finish(box, for_status)


def _next(pending: list[BoxRun], running: list[BoxRun]) -> BoxRun | None:
    """The first pending box whose target is not under test right now: one box has one cycle
    state, so two runs against the same address never overlap (bundled boxes never clash)."""
    busy = {r.spec.target for r in running if r.spec.target}
    return next((box for box in pending if not box.spec.target or box.spec.target not in busy), None)


def _signal_group(box: BoxRun, sig: signal.Signals) -> None:
    if box.proc is None or box.proc.returncode is not None:
        return
    with contextlib.suppress(ProcessLookupError, PermissionError):
        os.killpg(box.proc.pid, sig)  # its own session: the pid is the group id


@contextlib.contextmanager
def stop_on_signals(runner: FleetRunner) -> Iterator[FleetRunner]:
    """While inside: SIGINT, SIGTERM (and SIGHUP) stop the runner instead of killing the parent."""
    sigs = [signal.SIGINT, signal.SIGTERM] + ([signal.SIGHUP] if hasattr(signal, "SIGHUP") else [])
    previous = {}
    if threading.current_thread() is threading.main_thread():
        for sig in sigs:
            previous[sig] = signal.signal(sig, lambda num, frame: runner.stop(f"stopped by {signal.Signals(num).name}"))
    try:
        yield runner
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)

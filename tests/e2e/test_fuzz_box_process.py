"""The box as the fuzz command's child (processes): a bounded ring per incarnation, exit status and signal."""

from __future__ import annotations

import shlex
import sys
import time

import pytest

from conformance.fuzz.box_process import BoxProcess
from conformance.fuzz.last_words import RING_BYTES

pytestmark = pytest.mark.timeout(120)

PY = shlex.quote(sys.executable)


def wait_for(cond, seconds: float = 20.0) -> bool:  # type: ignore[no-untyped-def]
    deadline = time.monotonic() + seconds
    while not cond():
        if time.monotonic() > deadline:
            return False
        time.sleep(0.02)
    return True


def test_the_ring_keeps_the_last_64_kb_and_the_stop_signal() -> None:
    script = "import sys, time; sys.stdout.write('x' * 200000 + '\\nEND\\n'); sys.stdout.flush(); time.sleep(60)"
    box = BoxProcess(f"{PY} -c {shlex.quote(script)}", log=lambda _: None)
    inc = box.start()
    try:
        assert wait_for(lambda: inc.written >= 200005)
        running = box.last_words(0.0)
        assert running is not None and running.exit_status is None and running.kind == "running"
        assert len(running.tail) == RING_BYTES and running.truncated and running.tail.endswith("x\nEND\n")
    finally:
        box.stop()
    stopped = inc.last_words(5.0)
    assert stopped.exit_status is not None and stopped.exit_status != 0
    assert stopped.signal in ("SIGTERM", None) or stopped.exit_status == 143


def test_each_restart_is_a_new_incarnation_and_a_crash_is_headlined() -> None:
    script = "import os, sys, time; print('serving', flush=True); time.sleep(1); sys.stderr.write('Segmentation fault\\n'); os._exit(139)"
    box = BoxProcess(f"{PY} -c {shlex.quote(script)}", log=lambda _: None)
    try:
        box.start()
        first = box.current
        assert first is not None and first.status(10.0) == 139
        box.restart()
        assert len(box.incarnations) == 2 and box.incarnations[1] is box.current
        words = first.last_words(5.0)
        assert words.incarnation == 1 and words.kind == "crash" and words.headline == "Segmentation fault"
        assert words.signal == "SIGSEGV" and "serving" in words.tail
    finally:
        box.close()


def test_a_command_that_fails_at_once_is_an_error_with_its_words() -> None:
    box = BoxProcess("echo 'no such box' >&2; exit 3", log=lambda _: None)
    with pytest.raises(RuntimeError, match="exited 3"):
        box.start()
    words = box.last_words(1.0)
    assert words is not None and words.exit_status == 3 and "no such box" in words.tail

"""The box as the fuzzer's child: ``fuzz --restart-cmd CMD`` starts it, keeps what it writes, and restarts it.

Each run of the restart command is an *incarnation*: a child process in a session of
its own, its stdout and stderr read by a thread into a bounded ring (the last
:data:`~.last_words.RING_BYTES` bytes), its exit status kept. A command that stays in
the foreground *is* the box (``./aibox --port 9100``): everything it writes is kept.
A command that starts the box elsewhere and returns (``systemctl restart aibox``,
``docker restart aibox``) keeps only its own output, and the box's last words are
whatever that command printed.

Restarting stops the incarnation that is still running (SIGTERM to its process
group, then SIGKILL), and starts the next one. :meth:`BoxProcess.last_words` is what
the incarnation that died left behind (:mod:`.last_words`), attached to the finding.
"""

from __future__ import annotations

import contextlib
import os
import signal
import subprocess
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field

from .last_words import RING_BYTES, LastWords, last_words

#: How long a restart command may take to fail before the box is waited for instead.
FAIL_FAST_S = 0.5
#: How long an incarnation may take to stop after SIGTERM before SIGKILL.
STOP_S = 5.0


@dataclass
class Incarnation:
    """One run of the restart command."""

    number: int
    proc: subprocess.Popen[bytes]
    ring: bytearray = field(default_factory=bytearray)
    written: int = 0  # bytes the incarnation wrote in all (the ring keeps the last RING_BYTES)
    reader: threading.Thread | None = None

    def read(self) -> None:
        """The reader thread: the output into the ring until the pipe closes."""
        out = self.proc.stdout
        assert out is not None
        while True:
            try:
                chunk = os.read(out.fileno(), 65536)
            except (OSError, ValueError):
                return
            if not chunk:
                return
            self.written += len(chunk)
            self.ring += chunk
            if len(self.ring) > RING_BYTES:
                del self.ring[: len(self.ring) - RING_BYTES]

    def status(self, wait_s: float = 0.0) -> int | None:
        try:
            return self.proc.wait(wait_s) if wait_s else self.proc.poll()
        except subprocess.TimeoutExpired:
            return None

    def last_words(self, wait_s: float = 1.0) -> LastWords:
        """Its output and exit status (waiting ``wait_s`` for a dying process to finish exiting and writing)."""
        status = self.status(wait_s)
        if status is not None and self.reader is not None:
            self.reader.join(wait_s)
        return last_words(self.number, self.proc.pid, status, bytes(self.ring), self.written > len(self.ring))


class BoxProcess:
    """Starts, restarts and stops the box with a shell command, keeping each incarnation's last words."""

    def __init__(self, cmd: str, log: Callable[[str], None] = print) -> None:
        self.cmd = cmd
        self.log = log
        self.incarnations: list[Incarnation] = []

    @property
    def current(self) -> Incarnation | None:
        return self.incarnations[-1] if self.incarnations else None

    def start(self) -> Incarnation:
        """A new incarnation; raises RuntimeError when the command fails at once."""
        proc = subprocess.Popen(self.cmd, shell=True, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,  # noqa: S602
                                stderr=subprocess.STDOUT, start_new_session=True)
        inc = Incarnation(len(self.incarnations) + 1, proc)
        inc.reader = threading.Thread(target=inc.read, name=f"box-output-{inc.number}", daemon=True)
        inc.reader.start()
        self.incarnations.append(inc)
        status = inc.status(FAIL_FAST_S)
        if status:
            words = inc.last_words()
            raise RuntimeError(f"the restart command exited {status}" + (f": {words.headline}" if words.headline
                                                                         else ""))
        return inc

    def restart(self) -> None:
        """The campaign's restart: stop what still runs, start the next incarnation."""
        self.log(f"fuzz: restarting the box: {self.cmd}")
        self.stop()
        self.start()

    def stop(self) -> None:
        """Stop the current incarnation if it still runs (its process group: SIGTERM, then SIGKILL)."""
        inc = self.current
        if inc is None or inc.status() is not None:
            return
        for sig, wait in ((signal.SIGTERM, STOP_S), (signal.SIGKILL, STOP_S)):
            with contextlib.suppress(OSError):
                os.killpg(inc.proc.pid, sig)
            if inc.status(wait) is not None:
                break
        if inc.reader is not None:
            inc.reader.join(1.0)

    def last_words(self, wait_s: float = 1.0) -> LastWords | None:
        """What the current incarnation left behind (None before the first start)."""
        inc = self.current
        return inc.last_words(wait_s) if inc is not None else None

    def close(self) -> None:
        self.stop()
        time.sleep(0)  # let the reader threads see the pipes close


__all__ = ["BoxProcess", "Incarnation"]

"""Bringing a dead box back, and replaying a history of cases against it: what confirms and shrinks a death (R2).

* :func:`restart_command` turns ``fuzz --restart-cmd CMD`` into the campaign's restart:
  the shell command runs (bounded by :data:`RESTART_TIMEOUT_S`; its output is dropped; it
  may start the box in the background), then :func:`recover` waits for the box to answer
  a fresh connection.
* :class:`History` is the cases a box saw since the last good liveness check, each
  marked with whether it started a new connection; :func:`kills` replays one on fresh
  connections and checks liveness after it; :func:`shrink` (delta debugging, ddmin)
  finds the shortest history that still kills the box, bringing it back after every
  run that killed it.
"""

from __future__ import annotations

import subprocess
import time
from collections.abc import Callable
from dataclasses import dataclass

from ..harness.transcript import Transcript
from .config import CampaignConfig
from .executor import Executor, alive
from .strategies import FuzzCase

#: The longest a restart command may take.
RESTART_TIMEOUT_S = 60.0
#: A shrink stops after this many replays or seconds (what it has then is reported).
SHRINK_RUNS = 64
SHRINK_S = 60.0


def restart_command(cmd: str, log: Callable[[str], None] = print) -> Callable[[], None]:
    """A restart from a shell command (``fuzz --restart-cmd CMD``)."""

    def restart() -> None:
        log(f"fuzz: restarting the box: {cmd}")
        done = subprocess.run(cmd, shell=True, stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,  # noqa: S602
                              stderr=subprocess.DEVNULL, timeout=RESTART_TIMEOUT_S, check=False,
                              start_new_session=True)
        if done.returncode:
            raise RuntimeError(f"the restart command exited {done.returncode}")

    return restart


def recover(config: CampaignConfig, executor: Executor) -> bool:
    """Restart the box (when the campaign can) and wait until it answers a fresh connection."""
    if config.restart is not None:
        try:
            config.restart()
        except Exception as exc:  # noqa: BLE001 - reported; the box is then not back
            config.log(f"fuzz: could not restart the box: {exc}")
            return False
    wait = config.recover_s if config.recover_s is not None else executor.time_out_s
    deadline = time.monotonic() + wait
    while True:
        if alive(executor.check_alive()):
            return True
        if time.monotonic() >= deadline:
            return False
        time.sleep(0.1)


@dataclass(frozen=True)
class Step:
    """One case of a history, and whether it went on a new connection."""

    case: FuzzCase
    new_connection: bool


History = list[Step]


def kills(config: CampaignConfig, history: History, transcript: Transcript) -> bool:
    """Replay ``history`` (a new connection where a step says so), then check liveness: is the box dead?"""
    ex = Executor(config.target, config.profile, transcript, udp_target=config.udp_target, extension=config.extension,
                  liveness_every=10**9, settle_s=config.settle_s)
    try:
        for i, step in enumerate(history):
            if step.new_connection or i == 0:
                ex.drop_connection()
            ex.run(step.case, f"replaying the history before the death, {i + 1} of {len(history)}: "
                              f"{step.case.describe()}")
        ex.drop_connection()
        return not alive(ex.check_alive())
    finally:
        ex.close()


def shrink(config: CampaignConfig, history: History, transcript: Transcript,
           back: Callable[[], bool]) -> tuple[History, int]:
    """The shortest sub-history (ddmin) that still kills the box, and the replays it took.

    ``history`` is known to kill the box, which is dead now; ``back()`` brings it back
    (False: it did not come back, and the shrink stops with what it has)."""
    if not back():
        return history, 0
    runs, deadline = 0, time.monotonic() + SHRINK_S
    best, n = list(history), 2
    while len(best) >= 2 and runs < SHRINK_RUNS and time.monotonic() < deadline:
        size = -(-len(best) // n)
        chunks = [best[i : i + size] for i in range(0, len(best), size)]
        candidates = chunks + ([best[:i] + best[i + size :] for i in range(0, len(best), size)] if n > 2 else [])
        for cand in candidates:
            runs += 1
            if kills(config, _first_new(cand), transcript):
                best, n = cand, max(2, n - 1) if cand not in chunks else 2
                if not back():
                    return _first_new(best), runs
                break
            if runs >= SHRINK_RUNS or time.monotonic() >= deadline:
                break
        else:
            if n >= len(best):
                break
            n = min(len(best), 2 * n)
    return _first_new(best), runs


def _first_new(history: History) -> History:
    """A replayed history starts on a new connection."""
    if not history or history[0].new_connection:
        return list(history)
    return [Step(history[0].case, True), *history[1:]]


__all__ = ["RESTART_TIMEOUT_S", "SHRINK_RUNS", "History", "Step", "kills", "recover", "restart_command", "shrink"]

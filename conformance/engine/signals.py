"""SIGTERM and SIGHUP end a run the way Ctrl-C does, so its evidence is never lost.

A CI job that hits its time limit sends SIGTERM; a closed terminal sends SIGHUP. Both
become a KeyboardInterrupt in the main thread: pytest stops after the current case,
whose pcap is flushed, and the reports are written for the cases that ran (the run is
marked INCOMPLETE). While the reports are written (:func:`deferred`), a further
signal is remembered instead of cutting them short.
"""

from __future__ import annotations

import contextlib
import signal
import threading
from collections.abc import Iterator
from types import FrameType
from typing import Any

_SIGNALS = tuple(s for s in (getattr(signal, "SIGTERM", None), getattr(signal, "SIGHUP", None)) if s is not None)
_saved: dict[int, Any] = {}
_state = {"deferring": False, "pending": 0}


class Interrupted(KeyboardInterrupt):
    """The run was stopped by a signal (SIGTERM, SIGHUP)."""


def _handler(signum: int, frame: FrameType | None) -> None:
    if _state["deferring"]:
        _state["pending"] = signum
        return
    raise Interrupted(f"stopped by {signal.Signals(signum).name}")


def install() -> None:
    """SIGTERM/SIGHUP raise KeyboardInterrupt in the main thread (no-op elsewhere, or twice)."""
    if threading.current_thread() is not threading.main_thread() or _saved:
        return
    for sig in _SIGNALS:
        _saved[sig] = signal.signal(sig, _handler)


def restore() -> None:
    if threading.current_thread() is not threading.main_thread():
        return
    for sig, old in list(_saved.items()):
        signal.signal(sig, old)
        del _saved[sig]


@contextlib.contextmanager
def deferred() -> Iterator[None]:
    """Hold SIGINT, SIGTERM and SIGHUP while evidence is written (they act afterwards)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    old_int = signal.signal(signal.SIGINT, _handler)
    installed = {sig: signal.signal(sig, _handler) for sig in _SIGNALS}
    _state["deferring"], _state["pending"] = True, 0
    try:
        yield
    finally:
        _state["deferring"] = False
        signal.signal(signal.SIGINT, old_int)
        for sig, old in installed.items():
            signal.signal(sig, old)
        pending = _state["pending"]
        _state["pending"] = 0
        if pending:
            raise Interrupted(f"stopped by {signal.Signals(pending).name}")

"""The ``serve`` command's body: the reference box in the foreground until SIGINT/SIGTERM (its parser is
:mod:`conformance.commands.serve`)."""

from __future__ import annotations

import asyncio
import contextlib
import signal
import sys
from typing import IO, Any

from .behaviour import BoxConfig
from .loop import new_event_loop, run_loop
from .protocols import DEFAULT_MAX_CONNECTIONS
from .server import ReferenceBox


def raise_fd_limit(wanted: int) -> None:
    """Raise the soft open-files limit towards ``wanted`` (never above the hard limit)."""
    try:
        import resource
    except ImportError:  # pragma: no cover (not POSIX)
        return
    soft, hard = resource.getrlimit(resource.RLIMIT_NOFILE)
    target = wanted if hard == resource.RLIM_INFINITY else min(wanted, hard)
    if soft != resource.RLIM_INFINITY and soft < target:
        with contextlib.suppress(ValueError, OSError):
            resource.setrlimit(resource.RLIMIT_NOFILE, (target, hard))


async def serve(box: ReferenceBox, out: IO[str] = sys.stdout, err: IO[str] = sys.stderr) -> int:
    """Run ``box`` until SIGINT/SIGTERM; print the listening line first. Returns 0."""
    stop = asyncio.Event()
    loop = asyncio.get_running_loop()
    installed = []
    for sig in (signal.SIGINT, signal.SIGTERM):
        with contextlib.suppress(NotImplementedError, RuntimeError, ValueError):
            loop.add_signal_handler(sig, stop.set)
            installed.append(sig)
    try:
        await box.start()
        print(box.describe(), file=out, flush=True)
        await stop.wait()
    finally:
        await box.close()
        for sig in installed:
            loop.remove_signal_handler(sig)
    print(f"isight-conformance serve: stopped; {box.summary()}", file=err, flush=True)
    return 0


def main_serve(
    config: BoxConfig, *, loop: str = "asyncio", out: IO[str] = sys.stdout, err: IO[str] = sys.stderr, **box_kwargs: Any
) -> int:
    """The ``serve`` subcommand: a box in the foreground until SIGINT/SIGTERM."""
    new_event_loop(loop).close()  # fail early and clearly on an unknown/missing loop
    raise_fd_limit(int(box_kwargs.get("max_connections", DEFAULT_MAX_CONNECTIONS)) + 64)
    box = ReferenceBox(config, **box_kwargs)
    return int(run_loop(serve(box, out, err), loop))


__all__ = ["main_serve", "raise_fd_limit", "serve"]

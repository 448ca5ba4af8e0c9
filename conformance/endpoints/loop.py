"""Event-loop helpers: a fresh loop of a chosen kind (``asyncio`` or ``uvloop``), a coroutine run
to completion on it, and :class:`BoxThread`, a reference box on its own thread and loop for
synchronous code (tests, the suite, the bundled box)::

    with BoxThread(BoxConfig(not_ready=True)) as box:
        host, port = box.address
"""

from __future__ import annotations

import asyncio
import contextlib
import threading
from collections.abc import Callable
from typing import Any

from .behaviour import BoxBehaviour, BoxConfig
from .server import ReferenceBox


def new_event_loop(kind: str = "asyncio") -> asyncio.AbstractEventLoop:
    """A fresh loop: ``asyncio`` (the standard one) or ``uvloop`` (if installed)."""
    if kind == "uvloop":
        try:
            import uvloop
        except ImportError:
            raise ValueError("--loop uvloop: uvloop is not installed (pip install uvloop)") from None
        return uvloop.new_event_loop()
    if kind != "asyncio":
        raise ValueError(f"unknown event loop {kind!r}")
    return asyncio.new_event_loop()


def run_loop(coro: Any, kind: str = "asyncio") -> Any:
    """``asyncio.run`` with a choice of loop (works on Python 3.10 too)."""
    loop = new_event_loop(kind)
    try:
        asyncio.set_event_loop(loop)
        return loop.run_until_complete(coro)
    finally:
        try:
            pending = [t for t in asyncio.all_tasks(loop) if not t.done()]
            for task in pending:
                task.cancel()
            if pending:
                loop.run_until_complete(asyncio.gather(*pending, return_exceptions=True))
            loop.run_until_complete(loop.shutdown_asyncgens())
        finally:
            asyncio.set_event_loop(None)
            loop.close()



class BoxThread:
    """A :class:`ReferenceBox` on its own thread and event loop, for synchronous code.

    ``BoxThread(config).start()`` returns once the box listens (on a free port by
    default); ``.address`` is ``(host, tcp_port)``; ``.stop()`` closes it.
    """

    def __init__(self, config: BoxConfig | None = None, *, port: int = 0, **box_kwargs: Any) -> None:
        self._kwargs = dict(box_kwargs, port=port)
        self._config = config
        self.box: ReferenceBox | None = None
        self._thread: threading.Thread | None = None
        self._ready = threading.Event()
        self._error: BaseException | None = None
        self._loop: asyncio.AbstractEventLoop | None = None
        self._stop: asyncio.Event | None = None

    def start(self, timeout: float = 10.0) -> BoxThread:
        if self._thread is not None:
            raise RuntimeError("already started")
        self._thread = threading.Thread(target=self._run, name="isight-reference-box", daemon=True)
        self._thread.start()
        if not self._ready.wait(timeout):
            raise TimeoutError("the reference box did not start")
        if self._error is not None:
            raise self._error
        return self

    def _run(self) -> None:
        loop = asyncio.new_event_loop()
        self._loop = loop
        try:
            loop.run_until_complete(self._main())
        except BaseException as exc:  # reported to start()
            self._error = exc
            self._ready.set()
        finally:
            loop.close()

    async def _main(self) -> None:
        self._stop = asyncio.Event()
        async with ReferenceBox(self._config, **self._kwargs) as box:
            self.box = box
            self._ready.set()
            await self._stop.wait()

    def stop(self, timeout: float = 10.0) -> None:
        loop, thread = self._loop, self._thread
        if loop is None or thread is None or not thread.is_alive():
            return
        stop = self._stop
        if stop is not None:
            with contextlib.suppress(RuntimeError):  # the loop already closed
                loop.call_soon_threadsafe(stop.set)
        thread.join(timeout)

    def call(self, func: Callable[[], Any]) -> Any:
        """Run ``func()`` on the box's loop and return its result (for tests)."""
        if self._loop is None:
            raise RuntimeError("not started")
        result: list[Any] = []
        done = threading.Event()

        def run() -> None:
            try:
                result.append(func())
            finally:
                done.set()

        self._loop.call_soon_threadsafe(run)
        done.wait(10.0)
        return result[0] if result else None

    @property
    def address(self) -> tuple[str, int]:
        assert self.box is not None, "not started"
        return self.box.address

    @property
    def tcp_port(self) -> int:
        assert self.box is not None and self.box.tcp_port is not None, "not started"
        return self.box.tcp_port

    @property
    def udp_port(self) -> int | None:
        assert self.box is not None, "not started"
        return self.box.udp_port

    @property
    def behaviour(self) -> BoxBehaviour:
        assert self.box is not None, "not started"
        return self.box.behaviour

    def __enter__(self) -> BoxThread:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()


__all__ = ["BoxThread", "new_event_loop", "run_loop"]

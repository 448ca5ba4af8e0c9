"""The monitor's two small HTTP servers (``--metrics``, ``--http``), on the monitor's event loop.

No framework and no thread: a request is read with a bound on its size and time, only
``GET`` (and ``HEAD``) are served, and every response closes its connection but the
page's event stream (server-sent events, ``/events``), which gets the board's snapshot
each time it changes. Routes:

* ``--metrics``: ``/metrics`` (Prometheus text exposition);
* ``--http``: ``/`` (the page), ``/events``, ``/state.json``, ``/metrics`` too,
  ``/ring/<file>`` (a pcapng file of the ring, by its name only) and
  ``/reports/<file>`` (the reports of the last checkpoint or stop).

:func:`check_bind` refuses an address other than loopback unless the operator said so
(``--allow-remote``): the page and the metrics have no authentication and the ring's
files hold every byte of the line (see docs/MONITOR.md).
"""

from __future__ import annotations

import asyncio
import contextlib
import ipaddress
import json
from collections.abc import AsyncIterator, Callable
from pathlib import Path

__all__ = ["MAX_STREAMS", "Response", "WebServer", "check_bind", "is_loopback"]

MAX_REQUEST = 8192
READ_TIMEOUT_S = 10.0
MAX_STREAMS = 32  # event streams at once
MAX_CLIENTS = 64

Response = tuple[int, str, bytes]
Handler = Callable[[str], "Response | None"]


def is_loopback(host: str) -> bool:
    if host in ("localhost", "ip6-localhost"):
        return True
    try:
        return ipaddress.ip_address(host.strip("[]")).is_loopback
    except ValueError:
        return False


def check_bind(option: str, host: str, allow_remote: bool) -> None:
    """ValueError (one line) for a non-loopback ``host`` without ``--allow-remote``."""
    if not allow_remote and not is_loopback(host):
        raise ValueError(f"{option} {host}: not a loopback address; the page and the metrics have no "
                         "authentication and the ring's pcapng files hold every byte of the line. Add "
                         "--allow-remote to serve them on the network (see docs/MONITOR.md)")


_REASONS = {200: "OK", 400: "Bad Request", 404: "Not Found", 405: "Method Not Allowed", 503: "Service Unavailable"}


def _head(status: int, ctype: str, length: int | None) -> bytes:
    lines = [f"HTTP/1.1 {status} {_REASONS.get(status, 'OK')}", f"Content-Type: {ctype}", "Cache-Control: no-store",
             "X-Content-Type-Options: nosniff", "Connection: close"]
    if length is not None:
        lines.append(f"Content-Length: {length}")
    return ("\r\n".join(lines) + "\r\n\r\n").encode()


def file_response(directory: Path | None, name: str, allowed: set[str], ctype: str) -> Response | None:
    """A file of ``directory`` named exactly one of ``allowed`` (never a path), or None."""
    if directory is None or name not in allowed or "/" in name or name.startswith("."):
        return None
    try:
        return 200, ctype, (directory / name).read_bytes()
    except OSError:
        return None


class WebServer:
    """``handler(path)`` gives (status, content type, body) or None (404); ``events`` (if any) serves ``/events``."""

    def __init__(self, host: str, port: int, handler: Handler,
                 events: Callable[[], AsyncIterator[bytes]] | None = None) -> None:
        self.host, self.port = host, port
        self.handler = handler
        self.events = events
        self.server: asyncio.AbstractServer | None = None
        self.streams = 0
        self.clients: set[asyncio.Task[None]] = set()
        self.address: tuple[str, int] | None = None

    async def start(self) -> tuple[str, int]:
        self.server = await asyncio.start_server(self._client, self.host, self.port, limit=MAX_REQUEST)
        self.address = self.server.sockets[0].getsockname()[:2]
        return self.address

    async def stop(self) -> None:
        if self.server is not None:
            self.server.close()
        for task in list(self.clients):
            task.cancel()
        for task in list(self.clients):
            with contextlib.suppress(BaseException):
                await task
        if self.server is not None:
            with contextlib.suppress(Exception):
                await asyncio.wait_for(self.server.wait_closed(), 2.0)

    async def _client(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        task = asyncio.current_task()
        if task is None or len(self.clients) >= MAX_CLIENTS:
            writer.close()
            return
        self.clients.add(task)
        try:
            await self._serve(reader, writer)
        except (asyncio.CancelledError, ConnectionError, asyncio.IncompleteReadError, asyncio.LimitOverrunError,
                asyncio.TimeoutError, TimeoutError, ValueError):
            pass
        finally:
            self.clients.discard(task)
            with contextlib.suppress(Exception):
                writer.close()

    async def _serve(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        head = await asyncio.wait_for(reader.readuntil(b"\r\n\r\n"), READ_TIMEOUT_S)
        words = head.split(b"\r\n", 1)[0].decode("latin-1").split()
        if len(words) != 3:
            writer.write(_head(400, "text/plain", 12) + b"bad request\n")
            return
        method, target = words[0], words[1].split("?", 1)[0]
        if method not in ("GET", "HEAD"):
            writer.write(_head(405, "text/plain", 8) + b"GET only")
            return
        if target == "/events" and self.events is not None:
            await self._stream(writer, method == "HEAD")
            return
        response = self.handler(target)
        status, ctype, body = response if response is not None else (404, "text/plain", b"not found\n")
        writer.write(_head(status, ctype, len(body)) + (b"" if method == "HEAD" else body))
        await writer.drain()

    async def _stream(self, writer: asyncio.StreamWriter, head_only: bool) -> None:
        if self.streams >= MAX_STREAMS:
            writer.write(_head(503, "text/plain", 16) + b"too many streams")
            return
        writer.write(_head(200, "text/event-stream", None))
        if head_only:
            return
        assert self.events is not None
        self.streams += 1
        try:
            async for data in self.events():
                writer.write(b"data: " + data + b"\n\n")
                await asyncio.wait_for(writer.drain(), READ_TIMEOUT_S)  # a reader that stalls is dropped
        finally:
            self.streams -= 1


def json_response(doc: object) -> Response:
    return 200, "application/json; charset=utf-8", json.dumps(doc, ensure_ascii=False).encode()

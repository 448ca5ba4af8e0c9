"""The live page and the metrics, wired to one hub: started after the line listens, ticked with it.

:class:`LiveServers` owns the :class:`~.livestate.Board`, the metrics registry and the
:class:`~.webserve.WebServer` of ``--metrics`` and of ``--http`` (either may be absent).
Each tick the board takes its snapshot once and every open event stream gets it.
"""

from __future__ import annotations

import asyncio
import json
from collections.abc import AsyncIterator
from pathlib import Path

from .exposition import CONTENT_TYPE_LATEST, metrics_text, registry_for
from .hub import Hub
from .livepage import page
from .livestate import REPORTS, Board
from .webserve import Response, WebServer, file_response, json_response

__all__ = ["LiveServers"]


class LiveServers:
    def __init__(self, hub: Hub, report_dir: Path, metrics: tuple[str, int] | None,
                 http: tuple[str, int] | None) -> None:
        self.hub = hub
        self.report_dir = report_dir
        self.board = Board(hub)
        self.registry = registry_for(hub, lambda: self.board.pose_rate)
        self.metrics = WebServer(*metrics, self._metrics) if metrics is not None else None
        self.http = WebServer(*http, self._page, self._events) if http is not None else None
        self.snapshot = b"{}"
        self.changed = asyncio.Event()
        self.addresses: dict[str, tuple[str, int]] = {}

    async def start(self) -> dict[str, tuple[str, int]]:
        """Listen; the addresses got (``metrics``, ``http``). OSError when one cannot listen."""
        self.tick()
        try:
            if self.metrics is not None:
                self.addresses["metrics"] = await self.metrics.start()
            if self.http is not None:
                self.addresses["http"] = await self.http.start()
        except OSError:
            await self.stop()
            raise
        return self.addresses

    async def stop(self) -> None:
        for server in (self.metrics, self.http):
            if server is not None:
                await server.stop()

    def tick(self) -> None:
        self.board.tick()
        if self.http is not None:
            self.snapshot = json.dumps(self.board.snapshot(), ensure_ascii=False).encode()
            self.changed.set()
            self.changed = asyncio.Event()

    async def _events(self) -> AsyncIterator[bytes]:
        """The current snapshot at once for a new stream, then each new one."""
        yield self.snapshot
        while True:
            await self.changed.wait()
            yield self.snapshot

    # -- routes -------------------------------------------------------------------------------------
    def _metrics(self, path: str) -> Response | None:
        if path == "/metrics":
            return 200, CONTENT_TYPE_LATEST, metrics_text(self.registry)
        return None

    def _page(self, path: str) -> Response | None:
        s = self.hub.settings
        if path in ("/", "/index.html"):
            return 200, "text/html; charset=utf-8", page(f"{s.listen[0]}:{s.listen[1]}",
                                                          f"{s.upstream[0]}:{s.upstream[1]}")
        if path == "/state.json":
            return json_response(self.board.snapshot())
        if path == "/metrics":
            return self._metrics(path)
        if path.startswith("/ring/"):
            ring = self.hub.ring
            names = {p.name for p, _ in ring.kept} if ring is not None else set()
            return file_response(ring.directory if ring is not None else None, path[6:], names,
                                 "application/vnd.tcpdump.pcap")
        if path.startswith("/reports/"):
            name = path[9:]
            ctype = {"html": "text/html; charset=utf-8", "json": "application/json", "xml": "application/xml"}
            return file_response(self.report_dir, name, set(REPORTS), ctype.get(name.rsplit(".", 1)[-1], "text/plain"))
        return None

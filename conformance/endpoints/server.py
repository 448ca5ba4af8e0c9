"""The reference AI Box: asyncio TCP and UDP server around :mod:`.behaviour`.

``isight-conformance serve`` runs it (:mod:`.serve`); tests and the suite embed it with
:class:`ReferenceBox` (async) or :class:`~.loop.BoxThread` (a box on its own thread and
loop, for synchronous code)::

    async with ReferenceBox(BoxConfig(), host="127.0.0.1", port=0) as box:
        ...  # box.tcp_port, box.udp_port

    with BoxThread(BoxConfig(not_ready=True)) as box:
        host, port = box.address

The connections themselves (the hot path, back-pressure, admission and the idle sweep)
are :mod:`.protocols`; ``log`` writes a :class:`~.framelog.FrameLog`.
"""

from __future__ import annotations

import asyncio
import contextlib
from pathlib import Path
from typing import IO

from ..protocol import DEFAULT_PORT
from .behaviour import BoxBehaviour, BoxConfig
from .framelog import FrameLog
from .protocols import (
    DEFAULT_IDLE_TIMEOUT,
    DEFAULT_MAX_CONNECTIONS,
    BoxTcpProtocol,
    BoxUdpProtocol,
    ConnectionTable,
    format_address,
    listen,
    resolve,
)


class ReferenceBox(ConnectionTable):
    """The reference AI Box on an asyncio loop (TCP and, by default, UDP on the same port)."""

    def __init__(
        self,
        config: BoxConfig | None = None,
        *,
        host: str = "127.0.0.1",
        port: int = DEFAULT_PORT,
        udp: bool = True,
        udp_port: int | None = None,
        max_connections: int = DEFAULT_MAX_CONNECTIONS,
        idle_timeout: float = DEFAULT_IDLE_TIMEOUT,
        evict_after: float = 1.0,
        log: str | Path | IO[str] | FrameLog | None = None,
        behaviour: BoxBehaviour | None = None,
    ) -> None:
        if max_connections < 1:
            raise ValueError("max connections must be at least 1")
        if idle_timeout < 0:
            raise ValueError("idle timeout must be >= 0 (0 = off)")
        if not 0 <= port <= 65535 or (udp_port is not None and not 0 <= udp_port <= 65535):
            raise ValueError("ports must be 0..65535")
        super().__init__(behaviour or BoxBehaviour(config or BoxConfig()), max_connections, idle_timeout, evict_after)
        self.config = self.behaviour.config
        self.host = host
        self.port = port
        self.udp = udp
        self.udp_port_request = udp_port
        self._log_target = log
        self.tcp_port: int | None = None
        self.udp_port: int | None = None
        self.bound_host = host
        self._server: asyncio.AbstractServer | None = None
        self._udp_transport: asyncio.DatagramTransport | None = None
        self._sweeper: asyncio.Task[None] | None = None

    # -- lifecycle ------------------------------------------------------------------------------
    async def __aenter__(self) -> ReferenceBox:
        await self.start()
        return self

    async def __aexit__(self, *exc: object) -> None:
        await self.close()

    @property
    def address(self) -> tuple[str, int]:
        """(host, TCP port) once started."""
        if self.tcp_port is None:
            raise RuntimeError("the box is not started")
        return self.bound_host, self.tcp_port

    def describe(self) -> str:
        """``listening tcp HOST:PORT udp HOST:PORT`` (the ``serve`` command's first line)."""
        line = f"listening tcp {format_address(self.bound_host, self.tcp_port or 0)}"
        if self.udp_port is not None:
            line += f" udp {format_address(self.bound_host, self.udp_port)}"
        return line

    async def start(self) -> None:
        self.loop = asyncio.get_running_loop()
        target = self._log_target
        if target is not None:
            self.log = target if isinstance(target, FrameLog) else FrameLog(target)
        family, address = await resolve(self.loop, self.host)
        self.bound_host = address
        server, self._udp_transport = await listen(
            self.loop, family, address, self.port, lambda: BoxTcpProtocol(self),
            (lambda: BoxUdpProtocol(self)) if self.udp else None, self.udp_port_request, backlog=1024)
        if self._udp_transport is not None:
            self.udp_port = self._udp_transport.get_extra_info("sockname")[1]
        self._server = server
        self.tcp_port = server.sockets[0].getsockname()[1]
        self._sweeper = self.loop.create_task(self._sweep())

    async def close(self) -> None:
        """Stop listening, close every connection (answers already written are sent), flush the log."""
        if self._closing:
            return
        self._closing = True
        if self._sweeper is not None:
            self._sweeper.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await self._sweeper
        if self._server is not None:
            self._server.close()
        if self._udp_transport is not None:
            self._udp_transport.close()
        for conn in list(self.connections.values()):
            conn._close("box shutting down")
        # give the kernel the answers already written, then drop whoever is left
        deadline = self.loop.time() + 1.0
        while self.connections and self.loop.time() < deadline:
            await asyncio.sleep(0.01)
        for conn in list(self.connections.values()):
            if conn.transport is not None:
                conn.transport.abort()
        if self._server is not None:
            with contextlib.suppress(Exception):
                await asyncio.wait_for(self._server.wait_closed(), 2.0)
        await asyncio.sleep(0)
        if self.log is not None:
            self.log.close()

    def summary(self) -> str:
        s = self.behaviour.stats
        return (
            f"connections accepted {self.accepted} (peak {self.peak_connections}, refused {self.refused}, "
            f"evicted {self.evicted}, idle-closed {self.idle_closed}); requests {s.requests}, answers {s.answers}, "
            f"malformed {s.malformed}, not requests {s.not_requests}, UDP dropped {s.dropped_datagrams}"
        )


__all__ = ["ReferenceBox"]

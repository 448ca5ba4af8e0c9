"""The UDP side of the monitor (``--udp``): datagrams passed on unchanged, both ways (asyncio).

The monitor listens on the same address and port as for TCP. Each robot address
(host and port) gets its own socket towards the box, so the box's answers find their
way back; every datagram is recorded and judged as one packet of that robot's UDP
conversation. At most :data:`MAX_PEERS` robot addresses are followed at once (the one
silent longest is dropped), and a robot address silent for :data:`IDLE_S` is
forgotten: memory stays bounded. Faults apply to TCP only.
"""

from __future__ import annotations

import asyncio
import contextlib
from typing import Any

from .hub import Conn, Hub

__all__ = ["IDLE_S", "MAX_PEERS", "UdpProxy"]

MAX_PEERS = 1024
IDLE_S = 300.0


class _Upstream(asyncio.DatagramProtocol):
    def __init__(self, proxy: UdpProxy, robot: tuple[str, int], conn: Conn) -> None:
        self.proxy, self.robot, self.conn = proxy, robot, conn
        self.transport: asyncio.DatagramTransport | None = None
        self.last = 0.0

    def connection_made(self, transport: Any) -> None:
        self.transport = transport

    def datagram_received(self, data: bytes, addr: Any) -> None:
        proxy = self.proxy
        if proxy.transport is not None:
            proxy.transport.sendto(data, self.robot)
            proxy.hub.data(self.conn, False, data)

    def error_received(self, exc: Exception) -> None:
        self.proxy.hub.note(f"udp {self.conn.line.number}: the box's side: {exc}")


class UdpProxy(asyncio.DatagramProtocol):
    def __init__(self, hub: Hub) -> None:
        self.hub = hub
        self.transport: asyncio.DatagramTransport | None = None
        self.peers: dict[tuple[str, int], _Upstream] = {}
        self.pending: dict[tuple[str, int], list[bytes]] = {}
        self.address: tuple[str, int] | None = None

    async def start(self) -> tuple[str, int]:
        loop = asyncio.get_running_loop()
        host, port = self.hub.settings.listen
        transport, _ = await loop.create_datagram_endpoint(lambda: self, local_addr=(host, port))
        self.address = transport.get_extra_info("sockname")[:2]
        return self.address

    def connection_made(self, transport: Any) -> None:
        self.transport = transport

    def datagram_received(self, data: bytes, addr: Any) -> None:
        robot = (addr[0], addr[1])
        loop = asyncio.get_running_loop()
        up = self.peers.get(robot)
        if up is not None and up.transport is not None:
            up.last = loop.time()
            up.transport.sendto(data)
            self.hub.data(up.conn, True, data)
            return
        queue = self.pending.get(robot)
        if queue is not None:  # the socket towards the box is being made
            if len(queue) < 64:
                queue.append(data)
            return
        self.pending[robot] = [data]
        loop.create_task(self._open(robot))

    async def _open(self, robot: tuple[str, int]) -> None:
        loop = asyncio.get_running_loop()
        self._expire(loop.time())
        conn = self.hub.opened(robot, self.hub.settings.upstream, "udp")
        try:
            _, up = await loop.create_datagram_endpoint(lambda: _Upstream(self, robot, conn),
                                                        remote_addr=self.hub.settings.upstream)
        except OSError as exc:
            self.hub.note(f"udp {conn.line.number} from {robot[0]}:{robot[1]}: cannot reach the box: {exc}")
            self.pending.pop(robot, None)
            self.hub.gone(conn)
            return
        up.last = loop.time()
        self.peers[robot] = up
        for data in self.pending.pop(robot, []):
            if up.transport is not None:
                up.transport.sendto(data)
                self.hub.data(conn, True, data)

    def _expire(self, now: float) -> None:
        stale = [r for r, up in self.peers.items() if now - up.last > IDLE_S]
        while len(self.peers) - len(stale) >= MAX_PEERS:
            stale.append(min((r for r in self.peers if r not in stale), key=lambda r: self.peers[r].last))
        for robot in stale:
            up = self.peers.pop(robot)
            if up.transport is not None:
                up.transport.close()
            self.hub.gone(up.conn)

    async def stop(self) -> None:
        for up in self.peers.values():
            if up.transport is not None:
                with contextlib.suppress(Exception):
                    up.transport.close()
        self.peers.clear()
        if self.transport is not None:
            self.transport.close()

"""Datagrams to the box, and every datagram that comes back, wherever it comes from or goes to.

The cases' :class:`~.client.UdpChannel` is a *connected* socket: the kernel drops a datagram
that does not come from the box's port, and one sent to another port of ours never reaches
it. To tell where a box's answers go (F7), :class:`UdpProbe` sends from an unconnected socket
and also listens on its port's neighbours (+1, −1, when free): each datagram heard is kept
with the port it came from and the port it reached. Every wait is bounded; nothing raises
out of :meth:`UdpProbe.ask` (an ICMP "port unreachable" is recorded as ``refused``).
"""

from __future__ import annotations

import contextlib
import select
import socket
import time
from dataclasses import dataclass

from .target import Target
from .transcript import Endpoint, Kind, Transcript

#: the neighbours of the sending port also listened on (a box that answers to port + 1, say)
NEIGHBOURS = (1, -1)


@dataclass(frozen=True)
class Heard:
    """One datagram the box sent: its bytes, the port it came from, and which of our ports it reached."""

    data: bytes
    source_port: int
    offset: int  # 0: the sending port; else the neighbour (port + offset) it reached
    latency_s: float

    def to_dict(self) -> dict[str, object]:
        return {"hex": self.data.hex(), "source_port": self.source_port, "offset": self.offset,
                "latency_ms": round(self.latency_s * 1000, 1)}


@dataclass
class Asked:
    """What followed one datagram."""

    sent: bytes
    heard: list[Heard]
    refused: bool = False

    def to_dict(self) -> dict[str, object]:
        return {"sent": self.sent.hex(), "heard": [h.to_dict() for h in self.heard], "refused": self.refused}


class UdpProbe:
    """An unconnected UDP socket talking to ``target``, and its free neighbours listening (use as a context)."""

    def __init__(self, target: Target, transcript: Transcript, label: str = "diagnose-udp") -> None:
        self.target = target
        self.transcript = transcript
        family = socket.AF_INET6 if ":" in target.host else socket.AF_INET
        self.main = socket.socket(family, socket.SOCK_DGRAM)
        self.main.setblocking(False)
        self.main.bind((target.host, 0))
        self.port: int = self.main.getsockname()[1]
        self.socks: dict[int, socket.socket] = {0: self.main}
        for offset in NEIGHBOURS:
            if not 0 < self.port + offset < 65536:
                continue
            extra = socket.socket(family, socket.SOCK_DGRAM)
            try:
                extra.bind((target.host, self.port + offset))
            except OSError:
                extra.close()
                continue
            extra.setblocking(False)
            self.socks[offset] = extra
        info = transcript.open("udp", Endpoint(target.host, self.port), Endpoint(target.host, target.port), label)
        self.conn_id = info.conn

    def __enter__(self) -> UdpProbe:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        for sock in self.socks.values():
            with contextlib.suppress(OSError):
                sock.close()

    def ask(self, data: bytes, wait_s: float, settle_s: float = 0.05, note: str = "") -> Asked:
        """``data`` to the box; then every datagram heard until ``wait_s`` passed or, after the first,
        ``settle_s`` more."""
        start = time.monotonic()
        asked = Asked(data, [])
        try:
            self.main.sendto(data, (self.target.host, self.target.port))
        except OSError as exc:
            self.transcript.note(f"send failed: {exc.strerror or exc}", self.conn_id)
        self.transcript.add(self.conn_id, Kind.SEND, data, note)
        deadline = start + max(0.0, wait_s)
        while True:
            left = deadline - time.monotonic()
            if left <= 0:
                return asked
            ready, _, _ = select.select(list(self.socks.values()), [], [], left)
            for sock in ready:
                offset = next(k for k, v in self.socks.items() if v is sock)
                try:
                    got, peer = sock.recvfrom(65536)
                except BlockingIOError:
                    continue
                except OSError:  # ECONNREFUSED: an ICMP port unreachable for an earlier datagram
                    asked.refused = True
                    continue
                self.transcript.add(self.conn_id, Kind.RECV, got, f"from port {peer[1]} to port {self.port + offset}")
                asked.heard.append(Heard(got, int(peer[1]), offset, time.monotonic() - start))
                deadline = min(deadline, time.monotonic() + settle_s)

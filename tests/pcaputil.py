"""Tiny helpers to write test pcaps (scapy) for the Wireshark dissector test.

Only what the tests need: TCP connections with a proper 3-way handshake and consistent
sequence/ack numbers in both directions, and single UDP datagrams.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from scapy.layers.inet import IP, TCP, UDP
from scapy.layers.l2 import Ether
from scapy.packet import Raw
from scapy.utils import wrpcap

LOCALHOST = "127.0.0.1"


@dataclass
class TcpConnection:
    """One TCP connection between a client (robot) port and a server (box) port.

    `send(data, from_client=True)` appends one segment; the peer's ACK number follows.
    """

    client_port: int
    server_port: int
    client_isn: int = 1000
    server_isn: int = 5000
    packets: list = field(default_factory=list)

    def __post_init__(self) -> None:
        c, s = self.client_isn, self.server_isn
        self.packets.append(self._pkt(True, "S", c, 0))
        self.packets.append(self._pkt(False, "SA", s, c + 1))
        self.packets.append(self._pkt(True, "A", c + 1, s + 1))
        self._seq = {True: c + 1, False: s + 1}

    def _pkt(self, from_client: bool, flags: str, seq: int, ack: int, payload: bytes = b""):
        sport, dport = (self.client_port, self.server_port) if from_client else (self.server_port, self.client_port)
        p = (
            Ether()
            / IP(src=LOCALHOST, dst=LOCALHOST)
            / TCP(sport=sport, dport=dport, flags=flags, seq=seq, ack=ack, window=65535)
        )
        if payload:
            p = p / Raw(payload)
        return p

    def send(self, data: bytes, from_client: bool = True) -> None:
        seq, ack = self._seq[from_client], self._seq[not from_client]
        self.packets.append(self._pkt(from_client, "PA", seq, ack, data))
        self._seq[from_client] = seq + len(data)


def udp_datagram(data: bytes, sport: int, dport: int):
    return Ether() / IP(src=LOCALHOST, dst=LOCALHOST) / UDP(sport=sport, dport=dport) / Raw(data)


def write_pcap(path, packets) -> None:
    """Write packets with increasing timestamps (1 ms apart) so the order is stable."""
    for i, p in enumerate(packets):
        p.time = 1_700_000_000 + i / 1000
    wrpcap(str(path), packets)

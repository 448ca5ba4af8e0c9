"""Link, IP and TCP/UDP headers, parsed with ``struct`` (full scapy dissection is far
too slow for a capture of millions of frames).

:meth:`PacketDecoder.decode` takes one captured frame and its link type and returns
``(protocol, key, seq, ack, flags, payload, missing)`` for a TCP segment or UDP
datagram, or None for anything else (counted in :attr:`PacketDecoder.skipped`).

* ``key`` identifies the direction: source address, destination address, source
  port, destination port, as bytes (4 + 4 + 4 for IPv4, 16 + 16 + 4 for IPv6);
  :func:`reverse_key` is the other direction and :func:`endpoints` reads it back;
* ``payload`` stops where the IP header says the packet ends (Ethernet pads short
  frames); ``missing`` counts payload bytes the capture did not keep (a snap length
  shorter than the packet), which the reassembly treats as a gap.

Link types: Ethernet (with 802.1Q/802.1ad tags), Linux cooked (SLL, SLL2), raw IP,
BSD loopback (NULL, LOOP). IPv4 fragments are not reassembled (iSight segments are far
below any MTU); they are counted and skipped. IPv6 extension headers are walked.
"""

from __future__ import annotations

import ipaddress
import struct
from typing import Any

__all__ = ["ACK", "FIN", "PSH", "RST", "SYN", "TCP", "UDP", "PacketDecoder", "endpoints", "format_endpoint", "reverse_key"]

TCP, UDP = 6, 17
FIN, SYN, RST, PSH, ACK = 0x01, 0x02, 0x04, 0x08, 0x10

_SEQ_ACK_FLAGS = struct.Struct("!IIH").unpack_from
_U16 = struct.Struct("!H").unpack_from
_VLAN = (0x8100, 0x88A8, 0x9100)
_ETHERTYPE_IP = {0x0800: 4, 0x86DD: 6}
_IPV6_EXT = (0, 43, 60)  # hop-by-hop, routing, destination options
_LINK_NAMES = {1: "Ethernet", 113: "Linux cooked", 276: "Linux cooked v2", 101: "raw IP", 0: "BSD loopback",
               108: "OpenBSD loopback", 228: "raw IPv4", 229: "raw IPv6", 12: "raw IP"}


def reverse_key(key: bytes) -> bytes:
    """The key of the other direction."""
    n = (len(key) - 4) // 2
    return key[n : 2 * n] + key[:n] + key[2 * n + 2 :] + key[2 * n : 2 * n + 2]


def endpoints(key: bytes) -> tuple[tuple[str, int], tuple[str, int]]:
    """((source address, port), (destination address, port)) of a key."""
    n = (len(key) - 4) // 2
    src, dst = ipaddress.ip_address(key[:n]), ipaddress.ip_address(key[n : 2 * n])
    sport, dport = struct.unpack("!HH", key[2 * n :])
    return (str(src), sport), (str(dst), dport)


def format_endpoint(host: str, port: int) -> str:
    return f"[{host}]:{port}" if ":" in host else f"{host}:{port}"


class PacketDecoder:
    """Decode frames to TCP/UDP segments; ``skipped`` counts the rest by reason."""

    def __init__(self) -> None:
        self.skipped: dict[str, int] = {}

    def _skip(self, reason: str) -> None:
        self.skipped[reason] = self.skipped.get(reason, 0) + 1

    def decode(self, linktype: int, data: bytes) -> tuple[int, bytes, int, int, int, bytes, int] | None:
        link = self._link(linktype, data)
        ip = self._ip(data, *link) if link is not None else None
        return self._transport(data, *ip) if ip is not None else None

    def _drop(self, reason: str = "short frame") -> Any:
        """Count ``reason``; None (``return self._drop(...)`` from any of the steps below)."""
        self._skip(reason)
        return None

    def _link(self, linktype: int, data: bytes) -> tuple[int, int] | None:
        """(IP version, offset of the IP header) behind the link layer; None (counted) if not IP."""
        if linktype == 1:
            if len(data) < 34:
                return self._drop()
            et = (data[12] << 8) | data[13]
            off = 14
            while et in _VLAN:
                if len(data) < off + 4:
                    return self._drop()
                et = (data[off + 2] << 8) | data[off + 3]
                off += 4
            if et in _ETHERTYPE_IP:
                return _ETHERTYPE_IP[et], off
            return self._drop("not IP")
        if linktype in (101, 12, 14, 228, 229):
            return (data[0] >> 4 if data else 0), 0
        if linktype == 113 or linktype == 276:
            if len(data) < 20:
                return self._drop()
            et = (data[14] << 8 | data[15]) if linktype == 113 else (data[0] << 8 | data[1])
            return _ETHERTYPE_IP.get(et, 0), (16 if linktype == 113 else 20)
        if linktype in (0, 108):
            if len(data) < 5:
                return self._drop()
            return data[4] >> 4, 4
        return self._drop(f"link type {linktype} ({_LINK_NAMES.get(linktype, 'not supported')})")

    def _ip(self, data: bytes, v: int, off: int) -> tuple[int, int, int, bytes] | None:
        """(protocol, offset of its header, end of the packet, addresses) of the IP packet at ``off``."""
        size = len(data)
        if v == 4:
            if size < off + 20:
                return self._drop()
            if (data[off + 6] & 0x3F) or data[off + 7]:  # MF flag or a fragment offset
                return self._drop("IP fragment")
            total = (data[off + 2] << 8) | data[off + 3]
            return data[off + 9], off + (data[off] & 15) * 4, off + total, data[off + 12 : off + 20]
        if v != 6:
            return self._drop("not IP")
        if size < off + 40:
            return self._drop()
        proto = data[off + 6]
        end = off + 40 + ((data[off + 4] << 8) | data[off + 5])
        l4 = off + 40
        while proto in _IPV6_EXT or proto == 51:
            if size < l4 + 2:
                return self._drop()
            step = (data[l4 + 1] + 2) * 4 if proto == 51 else (data[l4 + 1] + 1) * 8
            proto = data[l4]
            l4 += step
        if proto == 44:
            return self._drop("IP fragment")
        return proto, l4, end, data[off + 8 : off + 40]

    def _transport(self, data: bytes, proto: int, l4: int, end: int,
                   addrs: bytes) -> tuple[int, bytes, int, int, int, bytes, int] | None:
        size = len(data)
        if proto == TCP:
            if size < l4 + 20:
                return self._drop("headers cut by the snap length")
            seq, ack, hl_flags = _SEQ_ACK_FLAGS(data, l4 + 4)
            start = l4 + ((hl_flags >> 12) << 2)
            payload = data[start:end] if end <= size else data[start:]
            missing = max(0, end - max(start, size)) if end > size else 0
            return TCP, addrs + data[l4 : l4 + 4], seq, ack, hl_flags & 0x3F, payload, missing
        if proto == UDP:
            if size < l4 + 8:
                return self._drop("headers cut by the snap length")
            udp_end = l4 + _U16(data, l4 + 4)[0]
            end = min(end, udp_end) if udp_end >= l4 + 8 else end
            payload = data[l4 + 8 : end] if end <= size else data[l4 + 8 :]
            missing = max(0, end - max(l4 + 8, size)) if end > size else 0
            return UDP, addrs + data[l4 : l4 + 4], 0, 0, 0, payload, missing
        return self._drop("not TCP or UDP")

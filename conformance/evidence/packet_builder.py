"""The packets a socket transcript implies: Ethernet, IP, TCP and UDP, and the TCP conversation of one connection.

A :class:`Flow` is one connection of a transcript as the wire would show it: its
addresses and ports, the next sequence number of each side, whether the handshake was
drawn, which side sent a FIN, whether it was reset. The functions here advance it and
return the frames (Ethernet, as Linux shows loopback; IPv4, or IPv6 for a host
containing ``:``):

* :func:`handshake`: SYN, SYN-ACK, ACK (MSS 65495, no window scaling; a passive open
  when the remote end sent the SYN);
* :func:`data`: segments of at most ``max_segment`` bytes (PSH on the last), each
  followed by the receiver's pure ACK; seq/ack advance with the bytes;
* :func:`fin`: FIN-ACK from the side that closed, ACK from the other;
* :func:`rst`: RST-ACK from the side that reset;
* :func:`connect_failed`: a SYN, and the server's RST-ACK when the connect was refused;
* :func:`udp`: one datagram.

IP and TCP/UDP checksums are correct (``tests/e2e/test_pcap.py`` compares the frames with
scapy's). The initial sequence numbers come from the case ID and connection number
(:func:`new_flow`), so the same transcript always gives the same bytes.
"""

from __future__ import annotations

import ipaddress
import struct
import zlib
from dataclasses import dataclass, field
from typing import Final

from conformance.harness.transcript import ConnectionInfo

__all__ = ["MAX_SEGMENT", "Flow", "connect_failed", "data", "fin", "handshake", "new_flow", "rst", "tcp", "udp"]

#: Largest TCP payload per synthesised segment: larger sends/recvs are split.
MAX_SEGMENT = 65000
#: Advertised MSS on SYN / SYN-ACK (Linux loopback: MTU 65536 - 40).
_MSS = 65495
_WINDOW = 65535

# TCP flags
_FIN, _SYN, _RST, _PSH, _ACK = 0x01, 0x02, 0x04, 0x08, 0x10

_ETH_IPV4 = bytes(12) + b"\x08\x00"  # zero MACs, as Linux loopback
_ETH_IPV6 = bytes(12) + b"\x86\xdd"
_IPV4 = struct.Struct("!BBHHHBBH4s4s")
_IPV6 = struct.Struct("!IHBB16s16s")
_TCP = struct.Struct("!HHIIBBHHH")
_UDP = struct.Struct("!HHHH")
_TCP_MSS_OPTION = struct.pack("!BBH", 2, 4, _MSS)
_PROTO_TCP, _PROTO_UDP = 6, 17
# An unused-by-Linux ephemeral range (Linux uses 32768-60999) for a failed connect
# whose local port was never known.
_SYNTHETIC_PORT_BASE = 61000


#: IP, TCP and UDP headers (and their checksums) are in network byte order, whatever the iSight profile says
_NETWORK_ORDER: Final = "big"


def _sum16(data: bytes) -> int:
    """The 16-bit words of ``data`` (even length) summed modulo 0xFFFF (2**16 == 1)."""
    return int.from_bytes(data, _NETWORK_ORDER) % 0xFFFF


def _fold(total: int) -> int:
    """The Internet checksum of words whose sum modulo 0xFFFF is ``total``.

    The words are never all zero here (an IP header, a pseudo-header with a protocol
    number), so a sum divisible by 0xFFFF is the ones'-complement 0xFFFF (-0), whose
    complement is 0x0000, as Linux and scapy write it."""
    total %= 0xFFFF
    return 0xFFFF - total if total else 0x0000


def _payload_sum(data: bytes) -> int:
    return _sum16(data + b"\x00" if len(data) & 1 else data)


# -- addresses -------------------------------------------------------------------------------
def _ip_or_none(host: str) -> ipaddress.IPv4Address | ipaddress.IPv6Address | None:
    try:
        return ipaddress.ip_address(host.split("%", 1)[0].strip("[]"))
    except ValueError:
        return None


def _address(host: str, want_v6: bool | None = None) -> tuple[bytes, bool]:
    """Packed address and family; a host name or wildcard becomes loopback."""
    addr = _ip_or_none(host)
    if addr is not None and not addr.is_unspecified and (want_v6 is None or (addr.version == 6) == want_v6):
        return addr.packed, addr.version == 6
    v6 = want_v6 if want_v6 is not None else ":" in host.split("%", 1)[0].strip("[]")
    return (ipaddress.IPv6Address("::1") if v6 else ipaddress.IPv4Address("127.0.0.1")).packed, v6


def _is_loopback(host: str) -> bool:
    addr = _ip_or_none(host)
    return host == "localhost" if addr is None else addr.is_loopback


# -- one connection ----------------------------------------------------------------------------
@dataclass
class Flow:
    info: ConnectionInfo
    v6: bool
    local: bytes
    remote: bytes
    lport: int
    rport: int
    seq: dict[bool, int]  # next sequence number, keyed by "from local"
    ip_id: dict[bool, int] = field(default_factory=lambda: {True: 0, False: 0})
    opened: bool = False  # handshake drawn
    fin: dict[bool, bool] = field(default_factory=lambda: {True: False, False: False})
    reset: bool = False


def new_flow(info: ConnectionInfo, case_id: str) -> Flow:
    """The connection's flow before its first packet; the ISNs are derived from ``case_id`` and its number."""
    remote, v6 = _address(info.remote.host)
    local_ip = _ip_or_none(info.local.host)
    if local_ip is not None and not local_ip.is_unspecified:
        local, _ = _address(info.local.host, v6)
    else:  # e.g. "0.0.0.0" of a connect that failed: the source was never known
        local = remote if _is_loopback(info.remote.host) else bytes(16 if v6 else 4)
    lport = info.local.port or _SYNTHETIC_PORT_BASE + info.conn % 4500
    seed = f"{case_id}/{info.conn}".encode()
    isn_local = zlib.crc32(seed + b"/local")
    isn_remote = zlib.crc32(seed + b"/remote")
    return Flow(info, v6, local, remote, lport, info.remote.port, {True: isn_local, False: isn_remote})


def handshake(flow: Flow, passive: bool) -> list[bytes]:
    """SYN, SYN-ACK, ACK; ``passive``: the remote end sent the SYN."""
    client = not passive  # True: we (local) sent the SYN
    syn_seq, synack_seq = flow.seq[client], flow.seq[not client]
    syn = tcp(flow, client, _SYN, seq=syn_seq, ack=0, options=_TCP_MSS_OPTION)
    flow.seq[client] = syn_seq + 1
    synack = tcp(flow, not client, _SYN | _ACK, seq=synack_seq, ack=syn_seq + 1, options=_TCP_MSS_OPTION)
    flow.seq[not client] = synack_seq + 1
    ack = tcp(flow, client, _ACK)
    flow.opened = True
    return [syn, synack, ack]


def connect_failed(flow: Flow, refused: bool) -> list[bytes]:
    """Our SYN, and the server's RST-ACK when the connect was ``refused``; the flow is then reset."""
    seq = flow.seq[True]
    frames = [tcp(flow, True, _SYN, seq=seq, ack=0, options=_TCP_MSS_OPTION)]
    if refused:
        frames.append(tcp(flow, False, _RST | _ACK, seq=0, ack=seq + 1))
    flow.reset = True
    return frames


def data(flow: Flow, out: bool, payload: bytes, max_segment: int = MAX_SEGMENT) -> list[bytes]:
    """``payload`` from one side (``out``: from local) in segments, each ACKed by the other side."""
    frames: list[bytes] = []
    size = len(payload)
    for start in range(0, size, max_segment):
        chunk = payload[start : start + max_segment]
        last = start + max_segment >= size
        frames.append(tcp(flow, out, _ACK | (_PSH if last else 0), payload=chunk))
        flow.seq[out] = (flow.seq[out] + len(chunk)) & 0xFFFFFFFF
        frames.append(tcp(flow, not out, _ACK))
    return frames


def fin(flow: Flow, out: bool) -> list[bytes]:
    """FIN-ACK from one side, ACK from the other."""
    frame = tcp(flow, out, _FIN | _ACK)
    flow.seq[out] = (flow.seq[out] + 1) & 0xFFFFFFFF
    flow.fin[out] = True
    return [frame, tcp(flow, not out, _ACK)]


def rst(flow: Flow, out: bool) -> bytes:
    """RST-ACK from one side; nothing more goes on the wire for the flow."""
    frame = tcp(flow, out, _RST | _ACK)
    flow.reset = True
    return frame


# -- headers -----------------------------------------------------------------------------------
def _ip(flow: Flow, out: bool, proto: int, segment_len: int) -> tuple[bytes, int]:
    """Ethernet + IP header for a segment, and the pseudo-header's checksum sum."""
    src, dst = (flow.local, flow.remote) if out else (flow.remote, flow.local)
    if flow.v6:
        ip = _IPV6.pack(0x60000000, segment_len & 0xFFFF, proto, 64, src, dst)
        pseudo = _sum16(src + dst) + segment_len + proto
        return _ETH_IPV6 + ip, pseudo
    ident = flow.ip_id[out]
    flow.ip_id[out] = (ident + 1) & 0xFFFF
    total = min(20 + segment_len, 0xFFFF)
    head = _IPV4.pack(0x45, 0, total, ident, 0x4000, 64, proto, 0, src, dst)
    csum = _fold(_sum16(head))
    head = head[:10] + csum.to_bytes(2, _NETWORK_ORDER) + head[12:]
    pseudo = _sum16(src + dst) + proto + segment_len
    return _ETH_IPV4 + head, pseudo


def tcp(
    flow: Flow,
    out: bool,
    flags: int,
    *,
    seq: int | None = None,
    ack: int | None = None,
    options: bytes = b"",
    payload: bytes = b"",
) -> bytes:
    """One TCP segment (``out``: from local); seq and ack default to where the flow is."""
    if seq is None:
        seq = flow.seq[out]
    if ack is None:
        ack = flow.seq[not out] if flags & _ACK else 0
    sport, dport = (flow.lport, flow.rport) if out else (flow.rport, flow.lport)
    hlen = 20 + len(options)
    head = _TCP.pack(sport, dport, seq & 0xFFFFFFFF, ack & 0xFFFFFFFF, (hlen // 4) << 4, flags, _WINDOW, 0, 0)
    head += options
    eth_ip, pseudo = _ip(flow, out, _PROTO_TCP, hlen + len(payload))
    csum = _fold(pseudo + _sum16(head) + (_payload_sum(payload) if payload else 0))
    return eth_ip + head[:16] + csum.to_bytes(2, _NETWORK_ORDER) + head[18:] + payload


def udp(flow: Flow, out: bool, payload: bytes) -> bytes:
    """One UDP datagram (``out``: from local)."""
    sport, dport = (flow.lport, flow.rport) if out else (flow.rport, flow.lport)
    length = 8 + len(payload)
    head = _UDP.pack(sport, dport, length & 0xFFFF, 0)
    eth_ip, pseudo = _ip(flow, out, _PROTO_UDP, length)
    csum = _fold(pseudo + _sum16(head) + _payload_sum(payload)) or 0xFFFF  # RFC 768: 0 means "none"
    return eth_ip + head[:6] + csum.to_bytes(2, _NETWORK_ORDER) + payload

"""Link, IP, TCP and UDP headers (conformance/analyze/capture_packets.py), against packets scapy builds
(explicit MAC addresses: scapy resolves nothing)."""

from __future__ import annotations

from scapy.layers.inet import IP, TCP, UDP
from scapy.layers.inet6 import IPv6, IPv6ExtHdrDestOpt
from scapy.layers.l2 import CookedLinux, Dot1Q, Ether
from scapy.packet import Raw

from conformance.analyze.capture_packets import ACK, FIN, PSH, SYN, PacketDecoder, endpoints, reverse_key
from conformance.analyze.capture_packets import TCP as P_TCP
from conformance.analyze.capture_packets import UDP as P_UDP

MACS = {"src": "02:00:00:00:00:01", "dst": "02:00:00:00:00:02"}


def decode(pkt, linktype=1):
    d = PacketDecoder()
    return d.decode(linktype, bytes(pkt)), d.skipped


def test_ethernet_ipv4_tcp():
    pkt = Ether(**MACS) / IP(src="10.0.0.2", dst="10.0.0.1") / TCP(sport=40000, dport=9004, seq=7, ack=9,
                                                                     flags="PA") / Raw(b"hello")
    (proto, key, seq, ack, flags, payload, missing), _ = decode(pkt)
    assert (proto, seq, ack, flags, payload, missing) == (P_TCP, 7, 9, PSH | ACK, b"hello", 0)
    assert endpoints(key) == (("10.0.0.2", 40000), ("10.0.0.1", 9004))
    assert endpoints(reverse_key(key)) == (("10.0.0.1", 9004), ("10.0.0.2", 40000))
    assert reverse_key(reverse_key(key)) == key


def test_ethernet_padding_is_not_payload():
    pkt = Ether(**MACS) / IP(src="10.0.0.2", dst="10.0.0.1") / TCP(flags="S", seq=1)
    raw = bytes(pkt) + b"\x00" * 6  # padded to the 60-byte Ethernet minimum
    (proto, _key, _seq, _ack, flags, payload, missing), = [PacketDecoder().decode(1, raw)]
    assert proto == P_TCP and flags == SYN and payload == b"" and missing == 0


def test_vlan_tags_ip_options_and_a_snap_length():
    pkt = (Ether(**MACS) / Dot1Q(vlan=5) / Dot1Q(vlan=6) / IP(src="10.0.0.2", dst="10.0.0.1", options=b"\x01" * 4)
           / TCP(sport=1, dport=2, flags="FA") / Raw(b"x" * 30))
    raw = bytes(pkt)[:-10]  # the capture kept 20 of the 30 payload bytes
    proto, _key, _seq, _ack, flags, payload, missing = PacketDecoder().decode(1, raw)
    assert flags == FIN | ACK and payload == b"x" * 20 and missing == 10


def test_ipv6_with_an_extension_header_and_udp():
    pkt = (Ether(**MACS) / IPv6(src="fd00::2", dst="fd00::1") / IPv6ExtHdrDestOpt() / UDP(sport=5, dport=9004)
           / Raw(b"abc"))
    (proto, key, *_rest, payload, missing), _ = decode(pkt)
    assert (proto, payload, missing) == (P_UDP, b"abc", 0)
    assert endpoints(key) == (("fd00::2", 5), ("fd00::1", 9004))


def test_linux_cooked_raw_ip_and_bsd_loopback():
    ip = IP(src="10.0.0.2", dst="10.0.0.1") / TCP(sport=1, dport=9004, flags="A") / Raw(b"zz")
    assert decode(CookedLinux(proto=0x0800) / ip, 113)[0][5] == b"zz"
    assert decode(ip, 101)[0][5] == b"zz"
    assert PacketDecoder().decode(0, b"\x02\x00\x00\x00" + bytes(ip))[5] == b"zz"


def test_what_is_not_tcp_or_udp_is_counted_and_skipped():
    d = PacketDecoder()
    assert d.decode(1, bytes(Ether(**MACS, type=0x0806) / Raw(bytes(28)))) is None
    frag = Ether(**MACS) / IP(src="10.0.0.2", dst="10.0.0.1", flags="MF") / TCP() / Raw(b"a")
    assert d.decode(1, bytes(frag)) is None
    assert d.decode(1, bytes(Ether(**MACS) / IP(src="10.0.0.2", dst="10.0.0.1", proto=1) / Raw(bytes(8)))) is None
    assert d.decode(147, b"\x00" * 40) is None
    assert d.skipped == {"not IP": 1, "IP fragment": 1, "not TCP or UDP": 1, "link type 147 (not supported)": 1}

"""The packets of one connection (conformance/evidence/packet_builder.py): handshake, seq/ack, FIN, RST, UDP.

Each frame is read back with scapy (no traffic: the bytes are only parsed). The byte
comparison with scapy's own checksums, and the files these packets go into, are in
``tests/e2e/test_pcap.py``.
"""

from __future__ import annotations

import zlib

import pytest
from scapy.layers.inet import IP, TCP, UDP
from scapy.layers.inet6 import IPv6
from scapy.layers.l2 import Ether

from conformance.evidence import packet_builder
from conformance.harness.transcript import ConnectionInfo, Endpoint


def flow(local: str = "127.0.0.1", remote: str = "127.0.0.1", lport: int = 40000, transport: str = "tcp",
         conn: int = 1) -> packet_builder.Flow:
    return packet_builder.new_flow(ConnectionInfo(conn, transport, Endpoint(local, lport), Endpoint(remote, 9004)), "T-001")


def tcp_of(frame: bytes) -> TCP:
    pkt = Ether(frame)
    assert TCP in pkt, pkt.summary()
    return pkt[TCP]


def flags(frame: bytes) -> str:
    return str(tcp_of(frame).flags)


def test_a_flow_starts_from_sequence_numbers_derived_from_the_case_and_connection() -> None:
    f = flow()
    assert f.seq == {True: zlib.crc32(b"T-001/1/local"), False: zlib.crc32(b"T-001/1/remote")}
    assert flow(conn=2).seq != f.seq
    assert (f.lport, f.rport, f.v6, f.opened, f.reset) == (40000, 9004, False, False, False)


def test_the_handshake_is_syn_synack_ack_with_the_mss_and_advances_both_sides() -> None:
    f = flow()
    isn_local, isn_remote = f.seq[True], f.seq[False]
    syn, synack, ack = packet_builder.handshake(f, passive=False)
    assert [flags(syn), flags(synack), flags(ack)] == ["S", "SA", "A"]
    assert tcp_of(syn).seq == isn_local and tcp_of(syn).options == [("MSS", 65495)]
    assert (tcp_of(synack).seq, tcp_of(synack).ack) == (isn_remote, isn_local + 1)
    assert (tcp_of(ack).seq, tcp_of(ack).ack) == (isn_local + 1, isn_remote + 1)
    assert (tcp_of(syn).sport, tcp_of(syn).dport) == (40000, 9004)
    assert f.opened and f.seq == {True: isn_local + 1, False: isn_remote + 1}


def test_a_passive_open_has_the_syn_come_from_the_remote_end() -> None:
    f = flow()
    syn, synack, _ = packet_builder.handshake(f, passive=True)
    assert flags(syn) == "S" and (tcp_of(syn).sport, tcp_of(syn).dport) == (9004, 40000)
    assert (tcp_of(synack).sport, tcp_of(synack).dport) == (40000, 9004)


def test_data_is_split_into_segments_each_acked_with_psh_on_the_last() -> None:
    f = flow()
    packet_builder.handshake(f, passive=False)
    start_local, start_remote = f.seq[True], f.seq[False]
    frames = packet_builder.data(f, True, bytes(range(250)), max_segment=100)
    assert [flags(x) for x in frames] == ["A", "A", "A", "A", "PA", "A"]
    segments = [tcp_of(x) for x in frames[::2]]
    assert [len(bytes(s.payload)) for s in segments] == [100, 100, 50]
    assert b"".join(bytes(s.payload) for s in segments) == bytes(range(250))
    assert [s.seq for s in segments] == [start_local, start_local + 100, start_local + 200]
    assert [tcp_of(x).ack for x in frames[1::2]] == [start_local + 100, start_local + 200, start_local + 250]
    assert all(tcp_of(x).seq == start_remote for x in frames[1::2])
    assert f.seq == {True: start_local + 250, False: start_remote}


def test_fin_and_rst() -> None:
    f = flow()
    packet_builder.handshake(f, passive=False)
    before = f.seq[False]
    fin, ack = packet_builder.fin(f, False)
    assert (flags(fin), flags(ack)) == ("FA", "A")
    assert tcp_of(ack).ack == before + 1 and f.fin == {True: False, False: True} and f.seq[False] == before + 1
    rst = packet_builder.rst(f, True)
    assert flags(rst) == "RA" and f.reset


@pytest.mark.parametrize("refused", [True, False])
def test_a_failed_connect_is_a_syn_and_the_servers_reset_when_refused(refused: bool) -> None:
    f = flow(local="0.0.0.0", lport=0)
    frames = packet_builder.connect_failed(f, refused)
    assert [flags(x) for x in frames] == (["S", "RA"] if refused else ["S"])
    assert tcp_of(frames[0]).sport >= 61000  # the local port was never known
    assert Ether(frames[0])[IP].src == "127.0.0.1"  # loopback target: loopback source
    assert f.reset and not f.opened


def test_ipv6_and_udp() -> None:
    f6 = flow(local="::1", remote="::1")
    syn = packet_builder.handshake(f6, passive=False)[0]
    assert IPv6 in Ether(syn) and Ether(syn)[IPv6].dst == "::1"
    fu = flow(transport="udp")
    datagram = Ether(packet_builder.udp(fu, False, b"\xfe\xfe payload"))
    assert (datagram[UDP].sport, datagram[UDP].dport, bytes(datagram[UDP].payload)) == (9004, 40000, b"\xfe\xfe payload")

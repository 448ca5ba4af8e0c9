"""The soak's pcap ring (issue 38): the hand-compiled ``tcp port P`` filter takes exactly that port's
packets, IPv4 and IPv6, with the loopback's outgoing copies dropped; the ring keeps what it should."""

from __future__ import annotations

import socket
import time
from pathlib import Path

import pytest

from conformance.soak.pcapring import PcapRing
from conformance.soak.sniff import Sniffer, SniffError, tcp_port_program
from conformance.soak.windows import Window


def sniffer(port: int) -> Sniffer:
    try:
        return Sniffer(port)
    except SniffError as exc:
        pytest.skip(str(exc))


def exchange(family: int, host: str, server: socket.socket) -> None:
    client = socket.socket(family)
    client.connect(server.getsockname()[:2])
    peer, _ = server.accept()
    client.sendall(b"ping")
    assert peer.recv(4) == b"ping"
    client.close()
    peer.close()


def read_packets(path: Path) -> list[bytes]:
    from scapy.utils import rdpcap

    return [bytes(p) for p in rdpcap(str(path))]


@pytest.mark.parametrize(("family", "host"), [(socket.AF_INET, "127.0.0.1"), (socket.AF_INET6, "::1")])
def test_only_the_ports_packets_once_each(tmp_path, family, host):
    server, other = socket.socket(family), socket.socket(family)
    for s in (server, other):
        try:
            s.bind((host, 0))
        except OSError as exc:
            pytest.skip(f"no {host}: {exc}")
        s.listen(2)
    port = server.getsockname()[1]
    sniff = sniffer(port)
    try:
        sniff.switch(tmp_path / "a.pcapng")
        exchange(family, host, server)
        exchange(family, host, other)  # another port: filtered out in the kernel
        time.sleep(0.3)
    finally:
        sniff.close()
        server.close()
        other.close()
    packets = read_packets(tmp_path / "a.pcapng")
    # SYN, SYN-ACK, ACK, data, its ACK, FIN/ACK, FIN/ACK, ACK (give or take a merged ACK), each once
    assert 6 <= len(packets) <= 10, len(packets)
    assert all(port.to_bytes(2, "big") in p[14:] for p in packets)


def test_the_filter_program_is_tcpdumps():
    program = tcp_port_program(9004)
    assert len(program) == 20 and program[-2] == (0x06, 0, 0, 262144) and program[-1] == (0x06, 0, 0, 0)
    assert program[1] == (0x15, 0, 6, 0x86DD)  # ip6: on to 2, else to 8
    assert sum(1 for code, _, _, k in program if code == 0x15 and k == 9004) == 4


def test_the_ring_keeps_the_newest_windows_and_every_window_with_a_finding(tmp_path):
    server = socket.socket()
    server.bind(("127.0.0.1", 0))
    server.listen(8)
    ring = PcapRing(tmp_path, server.getsockname()[1], keep=2)
    if ring.error:
        pytest.skip(ring.error)
    try:
        ring.start(0)
        for index in range(5):
            exchange(socket.AF_INET, "127.0.0.1", server)
            time.sleep(0.1)
            window = Window(index, 0.0, 5000)
            if index == 1:
                window.missing = 3  # a window with a finding
            ring.rotate(window.close(1.0, 0, {}, 0.0))
    finally:
        ring.close()
        server.close()
    names = sorted(p.name for p in tmp_path.iterdir())
    assert names == ["window-00001.pcapng", "window-00003.pcapng", "window-00004.pcapng"]
    assert ring.to_dict()["findings"] == ["window-00001.pcapng"] and ring.deleted == 2
    assert len(read_packets(tmp_path / "window-00001.pcapng")) >= 6

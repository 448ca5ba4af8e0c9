"""The pcapng container (conformance/evidence/pcapng.py): blocks, interfaces, comments, an unbuffered writer.

The file is parsed here block by block (the pcapng layout), and read with scapy's
reader; Wireshark/tshark reading whole recorded cases is in ``tests/e2e/test_pcap.py``.
"""

from __future__ import annotations

import struct
from pathlib import Path

from scapy.utils import PcapNgReader

from conformance.evidence.pcapng import LINKTYPE_ETHERNET, LINKTYPE_WIRESHARK_UPPER_PDU, PcapNgFile, pad4

FRAME = bytes(12) + b"\x08\x00" + bytes(27)  # an Ethernet header and an odd-length body


def blocks(path: Path) -> list[tuple[int, bytes]]:
    data = path.read_bytes()
    out, at = [], 0
    while at < len(data):
        kind, total = struct.unpack_from("<II", data, at)
        assert total % 4 == 0 and struct.unpack_from("<I", data, at + total - 4)[0] == total
        out.append((kind, data[at + 8 : at + total - 4]))
        at += total
    assert at == len(data)
    return out


def options(raw: bytes) -> list[tuple[int, bytes]]:
    out, at = [], 0
    while at < len(raw):
        code, length = struct.unpack_from("<HH", raw, at)
        if code == 0:
            break
        out.append((code, raw[at + 4 : at + 4 + length]))
        at += 4 + length + (-length % 4)
    return out


def test_pad4() -> None:
    assert [len(pad4(bytes(n))) for n in range(6)] == [0, 4, 4, 4, 4, 8]


def test_section_interfaces_and_packets_with_comments(tmp_path: Path) -> None:
    out = PcapNgFile(tmp_path / "a" / "x.pcapng", application="test app", comment="case T-1")
    first = out.add_interface(LINKTYPE_ETHERNET, "eth-like", "described")
    second = out.add_interface(LINKTYPE_WIRESHARK_UPPER_PDU, "notes")
    out.write_packet(FRAME, 1_700_000_000.123456, ["first packet", "ünïcode"])
    out.write(out.epb(FRAME[:14], 1_700_000_001.0, ifid=second))
    out.close()
    assert (first, second, out.packets, out.closed, out.error) == (0, 1, 2, True, None)
    shb, idb0, idb1, epb0, epb1 = blocks(tmp_path / "a" / "x.pcapng")
    assert shb[0] == 0x0A0D0D0A and struct.unpack_from("<IHH", shb[1]) == (0x1A2B3C4D, 1, 0)
    assert options(shb[1][16:]) == [(4, b"test app"), (1, b"case T-1")]
    assert struct.unpack_from("<H", idb0[1])[0] == LINKTYPE_ETHERNET
    assert options(idb0[1][8:]) == [(2, b"eth-like"), (3, b"described"), (9, b"\x06")]
    assert struct.unpack_from("<H", idb1[1])[0] == LINKTYPE_WIRESHARK_UPPER_PDU
    ifid, high, low, caplen, length = struct.unpack_from("<IIIII", epb0[1])
    assert (ifid, caplen, length, (high << 32) | low) == (0, len(FRAME), len(FRAME), 1_700_000_000_123_456)
    assert epb0[1][20 : 20 + len(FRAME)] == FRAME
    assert options(epb0[1][20 + len(FRAME) + (-len(FRAME) % 4) :]) == [(1, b"first packet"), (1, "ünïcode".encode())]
    assert struct.unpack_from("<I", epb1[1])[0] == 1
    packets = list(PcapNgReader(str(tmp_path / "a" / "x.pcapng")))
    assert [bytes(p) for p in packets] == [FRAME, FRAME[:14]]


def test_nothing_is_written_after_close(tmp_path: Path) -> None:
    out = PcapNgFile(tmp_path / "y.pcapng", application="test")
    out.add_interface(LINKTYPE_ETHERNET, "eth")
    size = (tmp_path / "y.pcapng").stat().st_size
    out.close()
    out.write_packet(FRAME, 0.0)
    out.close()  # idempotent
    assert (tmp_path / "y.pcapng").stat().st_size == size

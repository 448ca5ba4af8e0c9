"""The UDP and check-field defects of the independent boxes (issue 34, item 5), sans-I/O.

A conforming box checks and signs every datagram with CRC-16/MODBUS over bytes 0 .. 12+N×L−1,
takes exactly one frame per datagram, answers to the port the request came from and writes
00 00 in the TCP check field. Each defect here flips one of those:

* ``udp-crc-ccitt``: checks and signs with CRC-16/CCITT-FALSE (poly 0x1021, init 0xFFFF);
* ``udp-no-crc-check``: signs right but never checks the request's CRC;
* ``udp-crc-header``: checks and signs the CRC over the 12-byte header only (the blocks are not covered);
* ``udp-answer-port``: answers to the request's source port + 1;
* ``udp-two-frames``: takes every frame of a datagram and answers each (F7: one frame per datagram);
* ``tcp-check-crc``: writes the CRC-16/MODBUS of the answer in the TCP check field (F6: 00 00);
* ``tcp-crc-refused``: refuses a TCP request whose check field is not 00 00 (F6 SHOULD: ignore it).
"""

from __future__ import annotations

from . import wire_format as wire

UDP_DEFECTS = {"udp-crc-ccitt": "F7", "udp-no-crc-check": "R7", "udp-crc-header": "F7", "udp-answer-port": "F7",
               "udp-two-frames": "F7"}
CHECK_DEFECTS = {"tcp-check-crc": "F6", "tcp-crc-refused": "F6"}


def crc16_ccitt_false(data: bytes) -> int:
    crc = 0xFFFF
    for byte in data:
        crc ^= byte << 8
        for _ in range(8):
            crc = ((crc << 1) ^ 0x1021) & 0xFFFF if crc & 0x8000 else (crc << 1) & 0xFFFF
    return crc


def check_of(defect: str | None, frame: bytes) -> bytes:
    """The check field this box computes for ``frame`` (its check field excluded)."""
    if defect == "udp-crc-ccitt":
        return crc16_ccitt_false(frame).to_bytes(2, "big")
    if defect == "udp-crc-header":
        return wire.crc16_modbus(frame[: wire.HEADER_LEN]).to_bytes(2, "big")
    return wire.crc16_modbus(frame).to_bytes(2, "big")


def frames_of(defect: str | None, data: bytes) -> list[bytes]:
    """The frames this box takes from one datagram whose CRCs it accepts ([] : the datagram is dropped)."""
    if len(data) < wire.HEADER_LEN + wire.CHECK_LEN:
        return []
    if defect == "udp-two-frames":
        out = []
        while len(data) >= wire.HEADER_LEN + wire.CHECK_LEN:
            size = wire.Header.parse(data).frame_len
            if len(data) < size:
                break
            out.append(data[:size])
            data = data[size:]
        return [f for f in out if _checked(defect, f)]
    header = wire.Header.parse(data)
    if len(data) != header.frame_len or not _checked(defect, data):
        return []
    return [data]


def _checked(defect: str | None, frame: bytes) -> bool:
    return defect == "udp-no-crc-check" or frame[-2:] == check_of(defect, frame[:-2])


def sign(defect: str | None, answer: bytes) -> bytes:
    """A TCP answer (check 00 00) made into this box's datagram."""
    return answer[:-2] + check_of(defect, answer[:-2])


def reply_port(defect: str | None, port: int) -> int:
    """Where this box sends the answer to a datagram from ``port``."""
    return port + 1 if defect == "udp-answer-port" and port < 65535 else port


def tcp_check(defect: str | None, answer: bytes) -> bytes:
    """A TCP answer with this box's check field."""
    if defect == "tcp-check-crc" and len(answer) >= wire.HEADER_LEN + wire.CHECK_LEN:
        return answer[:-2] + wire.crc16_modbus(answer[:-2]).to_bytes(2, "big")
    return answer


def refuses_check(defect: str | None, frame: bytes) -> bool:
    """tcp-crc-refused: a TCP request whose check field is not 00 00 is a parse error to this box."""
    return defect == "tcp-crc-refused" and frame[-2:] != b"\0\0"

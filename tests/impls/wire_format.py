"""The iSight frame, written from PROTOCOL.md with ``struct`` (no project code).

Sans-I/O: header parsing, request checking and answer encoding. Shared by the boxes
and robots under ``tests/impls``; each box makes its own framing choices on top.
"""

from __future__ import annotations

import math
import struct
from collections.abc import Sequence
from dataclasses import dataclass

START = b"\xfe\xfe"
VERSION = 0x0001
ROBOT_TO_BOX = 0x01
BOX_TO_ROBOT = 0x10
HEADER = struct.Struct(">HHBBBBHH")  # start, version, transfer, action, block type, N, L, error
HEADER_LEN = 12
CHECK_LEN = 2

NONE, CYCLE_ON, CYCLE_OFF, POSE, REG_POSE, TOLERANCE, PROG_IDX, RESULT = 0x00, 0x01, 0x02, 0x23, 0x24, 0x25, 0x26, 0x27
CORE_ACTIONS = frozenset({NONE, CYCLE_ON, CYCLE_OFF, POSE, REG_POSE, TOLERANCE})
EXT_ACTIONS = frozenset({PROG_IDX, RESULT})

OK, NOT_READY, OFF_FAILED, POSE_ERROR, TOL_ERROR = 0x0000, 0x0001, 0x0002, 0x1001, 0x1002

#: action -> (block type, L, fewest N, most N) (B5; E2: ProgIdx carries exactly one block)
SHAPES: dict[int, tuple[int, int, int, int]] = {
    NONE: (0, 0, 0, 0), CYCLE_ON: (0, 0, 0, 0), CYCLE_OFF: (0, 0, 0, 0), RESULT: (0, 0, 0, 0),
    POSE: (1, 25, 1, 255), REG_POSE: (1, 25, 1, 255), TOLERANCE: (2, 5, 1, 255), PROG_IDX: (3, 5, 1, 1),
}
#: The largest body a legal request can carry: 255 pose blocks.
MAX_BODY = 255 * 25


@dataclass(frozen=True)
class Header:
    start: int
    version: int
    transfer: int
    action: int
    block_type: int
    count: int
    length: int
    error: int

    @classmethod
    def parse(cls, data: bytes | bytearray | memoryview, offset: int = 0) -> Header:
        return cls(*HEADER.unpack_from(data, offset))

    @property
    def body(self) -> int:
        return self.count * self.length

    @property
    def frame_len(self) -> int:
        return HEADER_LEN + self.body + CHECK_LEN

    def is_request_start(self) -> bool:
        """Start word and version right (what a trusting receiver checks first)."""
        return self.start == 0xFEFE and self.version == VERSION

    def shape_ok(self) -> bool:
        """Block type, N and L fit the action (B5); the action must be known."""
        shape = SHAPES.get(self.action)
        if shape is None:
            return False
        btype, length, fewest, most = shape
        return self.block_type == btype and self.length == length and fewest <= self.count <= most


@dataclass(frozen=True)
class Check:
    """How a box judges one complete request frame."""

    extension: bool = True
    first_index: int = 0
    reject_nan: bool = True
    #: F6: accept any TCP check field (True), or only 00 00 and the correct CRC (False).
    ignore_check: bool = True
    #: reject requests whose (undefined) error field is not 0000
    reject_request_error: bool = False


def known(action: int, extension: bool) -> bool:
    return action in CORE_ACTIONS or (extension and action in EXT_ACTIONS)


def not_a_request(h: Header, extension: bool) -> bool:
    """A5: wrong start word, version, transfer type or an unknown action."""
    return not h.is_request_start() or h.transfer != ROBOT_TO_BOX or not known(h.action, extension)


def blocks_ok(frame: bytes, h: Header, check: Check) -> bool:
    """B1-B4, E1: indexes from the first index rising by one, finite floats."""
    body = frame[HEADER_LEN : HEADER_LEN + h.body]
    for i in range(h.count):
        block = body[i * h.length : (i + 1) * h.length]
        if block[0] != (check.first_index + i) & 0xFF or check.first_index + i > 0xFF:
            return False
        if h.block_type in (1, 2) and check.reject_nan:
            floats = struct.unpack(f">{(h.length - 1) // 4}f", block[1:])
            if not all(math.isfinite(v) for v in floats):
                return False
    return True


def request_ok(frame: bytes, h: Header, check: Check) -> bool:
    """A whole frame with a request header for a known action: is it well-formed?"""
    if not h.shape_ok() or len(frame) != h.frame_len:
        return False
    if check.reject_request_error and h.error != 0:
        return False
    if not check.ignore_check:
        field = frame[-2:]
        if field != b"\0\0" and field != crc16_modbus(frame[:-2]).to_bytes(2, "big"):
            return False
    return blocks_ok(frame, h, check)


def crc16_modbus(data: bytes) -> int:
    crc = 0xFFFF
    for byte in data:
        crc ^= byte
        for _ in range(8):
            crc = (crc >> 1) ^ 0xA001 if crc & 1 else crc >> 1
    return crc


def encode(action: int, error: int = OK, value: int | None = None, *, transfer: int = BOX_TO_ROBOT,
           version: int = VERSION, first_index: int = 0) -> bytes:
    """An answer (or, with ``transfer=ROBOT_TO_BOX``, a blockless request) over TCP."""
    if value is None:
        return HEADER.pack(0xFEFE, version, transfer, action, 0, 0, 0, error) + b"\0\0"
    block = struct.pack(">Bi", first_index, value)
    return HEADER.pack(0xFEFE, version, transfer, action, 3, 1, 5, error) + block + b"\0\0"


def encode_request(action: int, blocks: Sequence[tuple[float, ...] | float | int] = (), *,
                   transfer: int = ROBOT_TO_BOX, first_index: int = 0, float_order: str = ">") -> bytes:
    """A robot's request: pose blocks (6 floats), tolerance blocks (1 float) or int32 values (type 03).

    ``float_order`` "<" writes the values little-endian (a broken robot, F4).
    """
    btype, length, _, _ = SHAPES[action]
    parts = []
    for i, block in enumerate(blocks):
        if btype == 3:
            parts.append(struct.pack(">B", first_index + i) + struct.pack(f"{float_order}i", int(block)))  # type: ignore[arg-type]
        else:
            values = block if isinstance(block, tuple) else (block,)
            parts.append(struct.pack(">B", first_index + i) + struct.pack(f"{float_order}{len(values)}f", *values))
    n = len(parts)
    head = HEADER.pack(0xFEFE, VERSION, transfer, action, btype if n else 0, n, length if n else 0, 0)
    return head + b"".join(parts) + b"\0\0"


@dataclass(frozen=True)
class Answer:
    """One decoded answer (what a robot reads back)."""

    header: Header
    value: int | None

    @property
    def action(self) -> int:
        return self.header.action

    @property
    def error(self) -> int:
        return self.header.error


def split_answers(buf: bytearray) -> list[Answer]:
    """Take every complete answer off the front of ``buf`` (a robot's reader); garbage raises ValueError."""
    out = []
    while len(buf) >= HEADER_LEN:
        h = Header.parse(buf)
        if h.start != 0xFEFE or h.body > MAX_BODY:
            raise ValueError(f"not an answer: {bytes(buf[:HEADER_LEN]).hex()}")
        if len(buf) < h.frame_len:
            break
        value = struct.unpack_from(">i", buf, HEADER_LEN + 1)[0] if h.block_type == 3 and h.count else None
        out.append(Answer(h, value))
        del buf[: h.frame_len]
    return out

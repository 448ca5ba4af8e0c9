"""Wire constants of the iSight frame (PROTOCOL.md, clauses F, B, A, E).

Every value that travels on the wire is an ``IntEnum`` so that logs, reports and
error messages print a name, and every layout number lives here once.
"""

from __future__ import annotations

import enum
import struct

START_WORD = 0xFEFE  # F1
#: The start word as it stands on the wire (the same in either byte order).
START_BYTES = START_WORD.to_bytes(2, "big")
VERSION = 0x0001  # F2
HEADER_LEN = 12  # 2+2+1+1+1+1+2+2
CHECK_LEN = 2  # F6 / F7
POSE_BLOCK_LEN = 25  # B1: index + 6 x float32
TOLERANCE_BLOCK_LEN = 5  # B2: index + float32
VALUE_BLOCK_LEN = 5  # E1: index + int32
MAX_BLOCK_COUNT = 255  # one byte
MAX_BLOCK_LEN = POSE_BLOCK_LEN  # the longest legal block
#: The largest frame any legal header can announce: 255 pose blocks.
MAX_FRAME_LEN = HEADER_LEN + MAX_BLOCK_COUNT * MAX_BLOCK_LEN + CHECK_LEN  # 6389
#: Where each header field lies: name -> (offset in the header, width in bytes), in wire order.
HEADER_FIELDS: dict[str, tuple[int, int]] = {
    "start_word": (0, 2), "version": (2, 2), "transfer_type": (4, 1), "action": (5, 1),
    "block_type": (6, 1), "block_count": (7, 1), "block_length": (8, 2), "error_code": (10, 2),
}
#: Default TCP/UDP port seen in the field (extension install guide).
DEFAULT_PORT = 9004


class TransferType(enum.IntEnum):
    """F3: the direction of a frame."""

    ROBOT_TO_BOX = 0x01
    BOX_TO_ROBOT = 0x10


class Action(enum.IntEnum):
    """Action field (header offset 5). 0x26/0x27 come from the extension (E)."""

    NONE = 0x00
    CYCLE_ON = 0x01
    CYCLE_OFF = 0x02
    POSE = 0x23
    REGISTER_POSE = 0x24
    TOLERANCE = 0x25
    PROG_IDX = 0x26
    VISION_RESULT = 0x27


def action_name(action: int | None, none: str = "bytes that are not a request") -> str:
    """An action byte as the reports write it: its name, ``0x..`` when it names no action, ``none`` for None."""
    if action is None:
        return none
    try:
        return Action(action).name
    except ValueError:
        return f"0x{action:02X}"


class BlockType(enum.IntEnum):
    """Block type field (header offset 6). 0x03 comes from the extension (E1)."""

    EMPTY = 0x00
    POSE = 0x01
    TOLERANCE = 0x02
    VALUE = 0x03


class ErrorCode(enum.IntEnum):
    """A3: error codes carried in an answer's header."""

    OK = 0x0000
    NOT_READY = 0x0001
    CYCLE_OFF_FAILED = 0x0002
    POSE_ERROR = 0x1001
    TOLERANCE_ERROR = 0x1002


class ResultCode(enum.IntEnum):
    """E2/E3: values carried in a type-03 block of a 0x26/0x27 answer."""

    EMPTY = 0  # the robot's initial value; never sent by the box
    OK = 1
    NG = 2
    OK_WITH_FAULT = 10
    NG_WITH_FAULT = 20
    BUSY = 202
    NOT_UNDERSTOOD = 400
    NO_ANSWER = 404  # written by the robot on vision_time_out; never sent by the box
    CONFLICT = 409


class Transport(str, enum.Enum):
    TCP = "tcp"
    UDP = "udp"


#: Block length (L) for each block type (B1, B2, E1).
BLOCK_LEN: dict[BlockType, int] = {
    BlockType.EMPTY: 0,
    BlockType.POSE: POSE_BLOCK_LEN,
    BlockType.TOLERANCE: TOLERANCE_BLOCK_LEN,
    BlockType.VALUE: VALUE_BLOCK_LEN,
}

#: The clause that defines each block type's layout.
BLOCK_CLAUSE: dict[BlockType, str] = {
    BlockType.EMPTY: "B5",
    BlockType.POSE: "B1",
    BlockType.TOLERANCE: "B2",
    BlockType.VALUE: "E1",
}

#: The error an answer SHOULD carry when a request with this action is malformed (A3).
ACTION_ERROR: dict[Action, ErrorCode] = {
    Action.POSE: ErrorCode.POSE_ERROR,
    Action.REGISTER_POSE: ErrorCode.POSE_ERROR,
    Action.TOLERANCE: ErrorCode.TOLERANCE_ERROR,
}

#: Actions that belong to the optional extension (E).
EXTENSION_ACTIONS = frozenset({Action.PROG_IDX, Action.VISION_RESULT})


class Shape(tuple):
    """(block type, fewest blocks, most blocks, clause) an action's frame must have."""

    __slots__ = ()

    def __new__(cls, block_type: BlockType, low: int, high: int, clause: str) -> Shape:
        return tuple.__new__(cls, (block_type, low, high, clause))

    block_type = property(lambda self: self[0])
    low = property(lambda self: self[1])
    high = property(lambda self: self[2])
    clause = property(lambda self: self[3])


_EMPTY_REQ = Shape(BlockType.EMPTY, 0, 0, "B5")
_EMPTY_ANS = Shape(BlockType.EMPTY, 0, 0, "A2")

#: B5 / E2 / E3: what each request must carry, by action.
REQUEST_SHAPE: dict[Action, Shape] = {
    Action.NONE: _EMPTY_REQ,
    Action.CYCLE_ON: _EMPTY_REQ,
    Action.CYCLE_OFF: _EMPTY_REQ,
    Action.POSE: Shape(BlockType.POSE, 1, MAX_BLOCK_COUNT, "B5"),
    Action.REGISTER_POSE: Shape(BlockType.POSE, 1, MAX_BLOCK_COUNT, "B5"),
    Action.TOLERANCE: Shape(BlockType.TOLERANCE, 1, MAX_BLOCK_COUNT, "B5"),
    Action.PROG_IDX: Shape(BlockType.VALUE, 1, 1, "E2"),
    Action.VISION_RESULT: Shape(BlockType.EMPTY, 0, 0, "E3"),
}

#: A2 / E2 / E3: what each answer must carry, by action.
ANSWER_SHAPE: dict[Action, Shape] = {
    **{action: _EMPTY_ANS for action in REQUEST_SHAPE},
    Action.PROG_IDX: Shape(BlockType.VALUE, 1, 1, "E2"),
    Action.VISION_RESULT: Shape(BlockType.VALUE, 1, 1, "E3"),
}

SHAPES: dict[TransferType, dict[Action, Shape]] = {
    TransferType.ROBOT_TO_BOX: REQUEST_SHAPE,
    TransferType.BOX_TO_ROBOT: ANSWER_SHAPE,
}


def f32_bits(value: float) -> int:
    """The IEEE-754 binary32 bit pattern of ``value`` as an integer (B4; independent of any byte order)."""
    return int(struct.unpack("=I", struct.pack("=f", value))[0])


def f32_of_bits(bits: int) -> float:
    """The float32 with this bit pattern (encoding it again gives the same bits)."""
    return float(struct.unpack("=f", struct.pack("=I", bits))[0])


#: Legal float32 values a hurried implementation gets wrong (B4: any finite float32 is a value): (id, bit pattern)
EDGE_FLOAT32 = (
    ("neg-zero", 0x80000000),
    ("min-subnormal", 0x00000001),
    ("neg-min-subnormal", 0x80000001),
    ("max-subnormal", 0x007FFFFF),
    ("min-normal", 0x00800000),
    ("max-float32", 0x7F7FFFFF),
    ("neg-max-float32", 0xFF7FFFFF),
)

"""Frames and blocks as frozen dataclasses (PROTOCOL.md F, B, E1).

A :class:`Frame` is a *well-formed* frame: its start word, version, block type,
block count and block length follow from its fields, so they are not stored.
:class:`Header` holds the twelve raw header bytes as integers, legal or not; it is
what errors carry and what fuzzers craft.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field, fields
from typing import Any, ClassVar, cast

from .constants import (
    BLOCK_LEN,
    START_WORD,
    VERSION,
    Action,
    BlockType,
    ErrorCode,
    TransferType,
)


@dataclass(frozen=True, slots=True)
class Header:
    """The twelve header bytes as integers, exactly as on the wire (legal or not)."""

    start_word: int = START_WORD
    version: int = VERSION
    transfer_type: int = TransferType.ROBOT_TO_BOX
    action: int = Action.NONE
    block_type: int = BlockType.EMPTY
    block_count: int = 0
    block_length: int = 0
    error_code: int = 0

    @property
    def body_length(self) -> int:
        """N*L: the number of block bytes this header announces."""
        return self.block_count * self.block_length


@dataclass(frozen=True, slots=True)
class PoseBlock:
    """B1: index + x, y, z, w, p, r as float32 (L = 25)."""

    index: int
    pose: tuple[float, float, float, float, float, float]
    block_type: ClassVar[BlockType] = BlockType.POSE


@dataclass(frozen=True, slots=True)
class ToleranceBlock:
    """B2: index + tolerance as float32 (L = 5)."""

    index: int
    tolerance: float
    block_type: ClassVar[BlockType] = BlockType.TOLERANCE


@dataclass(frozen=True, slots=True)
class ValueBlock:
    """E1: index + signed int32 (L = 5): a program index or a result code."""

    index: int
    value: int
    block_type: ClassVar[BlockType] = BlockType.VALUE


Block = PoseBlock | ToleranceBlock | ValueBlock


@dataclass(frozen=True, slots=True)
class Frame:
    """A well-formed frame. ``check`` is the value read off the wire (ignored on
    encode, which computes it for the transport) and does not take part in equality."""

    transfer_type: TransferType
    action: Action
    blocks: tuple[Block, ...] = ()
    error_code: int = ErrorCode.OK
    check: int = field(default=0, compare=False)

    @property
    def block_type(self) -> BlockType:
        return self.blocks[0].block_type if self.blocks else BlockType.EMPTY

    @property
    def block_length(self) -> int:
        return BLOCK_LEN[self.block_type]

    @property
    def header(self) -> Header:
        return Header(
            START_WORD,
            VERSION,
            self.transfer_type,
            self.action,
            self.block_type,
            len(self.blocks),
            self.block_length,
            self.error_code,
        )

    @property
    def is_request(self) -> bool:
        return self.transfer_type == TransferType.ROBOT_TO_BOX

    def describe(self) -> str:
        """One line for timelines and logs, e.g. ``robot→box POSE ×1 err=0x0000``."""
        arrow = "robot→box" if self.is_request else "box→robot"
        blocks = f" ×{len(self.blocks)}" if self.blocks else ""
        values = ""
        if self.blocks and isinstance(self.blocks[0], ValueBlock):
            values = " value=" + ",".join(str(b.value) for b in self.blocks if isinstance(b, ValueBlock))
        return f"{arrow} {self.action.name}{blocks}{values} err=0x{self.error_code:04X}"


# -- building without the generated __init__ (the decoder's hot path) ----------------------
# A frozen dataclass's __init__ stores each field with object.__setattr__, and that lookup per
# field puts the decoder over twice the struct baseline of benchmarks/bench_codec.py. The
# decoder builds Frame and PoseBlock by storing each slot through its descriptor (the store
# object.__setattr__ ends in). The objects are born Frame and PoseBlock: they compare, hash,
# print and refuse assignment like constructor-built ones (tests/unit/test_frames.py checks it).
def _slot_setters(cls: type, *names: str) -> tuple[Callable[[object, Any], None], ...]:
    """The descriptor stores of a slotted dataclass's fields, which must be ``names``, in order."""
    if names != tuple(f.name for f in fields(cls)):
        raise TypeError(f"{cls.__name__} fields are {[f.name for f in fields(cls)]}, not {list(names)}")
    return tuple(vars(cls)[name].__set__ for name in names)


_new = object.__new__
_set_transfer_type, _set_action, _set_blocks, _set_error_code, _set_check = _slot_setters(
    Frame, "transfer_type", "action", "blocks", "error_code", "check"
)
_set_index, _set_pose = _slot_setters(PoseBlock, "index", "pose")


def new_frame(
    transfer_type: TransferType, action: Action, blocks: tuple[Block, ...], error_code: int, check: int
) -> Frame:
    """``Frame(transfer_type, action, blocks, error_code, check)``, cheaper."""
    frame = _new(Frame)
    _set_transfer_type(frame, transfer_type)
    _set_action(frame, action)
    _set_blocks(frame, blocks)
    _set_error_code(frame, error_code)
    _set_check(frame, check)
    return frame


def new_pose_block(index: int, pose: tuple[float, float, float, float, float, float]) -> PoseBlock:
    """``PoseBlock(index, pose)``, cheaper."""
    block = _new(PoseBlock)
    _set_index(block, index)
    _set_pose(block, pose)
    return block


def new_pose_blocks(flat: tuple[Any, ...], count: int) -> tuple[PoseBlock, ...]:
    """``count`` PoseBlocks from a flat run ``index, x, y, z, w, p, r, index, x, ...`` (as struct unpacks them)."""
    blocks = []
    for k in range(0, 7 * count, 7):  # new_pose_block inlined: 6 % of a 10-pose decode
        block = _new(PoseBlock)
        _set_index(block, flat[k])
        _set_pose(block, flat[k + 1 : k + 7])
        blocks.append(block)
    return tuple(blocks)


# -- builders ----------------------------------------------------------------------


def pose_blocks(poses: Iterable[Sequence[float]], first_index: int = 0) -> tuple[PoseBlock, ...]:
    return tuple(
        PoseBlock(first_index + i, cast("tuple[float, float, float, float, float, float]", tuple(float(v) for v in p)))
        for i, p in enumerate(poses)
    )


def tolerance_blocks(values: Iterable[float], first_index: int = 0) -> tuple[ToleranceBlock, ...]:
    return tuple(ToleranceBlock(first_index + i, float(v)) for i, v in enumerate(values))


def value_blocks(values: Iterable[int], first_index: int = 0) -> tuple[ValueBlock, ...]:
    return tuple(ValueBlock(first_index + i, int(v)) for i, v in enumerate(values))


def request(action: Action, blocks: Iterable[Block] = (), error_code: int = 0) -> Frame:
    """A robot→box frame."""
    return Frame(TransferType.ROBOT_TO_BOX, Action(action), tuple(blocks), error_code)


def answer(action: Action, error_code: int = ErrorCode.OK, blocks: Iterable[Block] = ()) -> Frame:
    """A box→robot frame."""
    return Frame(TransferType.BOX_TO_ROBOT, Action(action), tuple(blocks), error_code)

"""Frames and blocks as frozen dataclasses (PROTOCOL.md F, B, E1).

A :class:`Frame` is a *well-formed* frame: its start word, version, block type,
block count and block length follow from its fields, so they are not stored.
:class:`Header` holds the twelve raw header bytes as integers, legal or not; it is
what errors carry and what fuzzers craft.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from typing import ClassVar

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
            values = " value=" + ",".join(str(b.value) for b in self.blocks)  # type: ignore[union-attr]
        return f"{arrow} {self.action.name}{blocks}{values} err=0x{self.error_code:04X}"


# -- builders ----------------------------------------------------------------------


def pose_blocks(poses: Iterable[Sequence[float]], first_index: int = 0) -> tuple[PoseBlock, ...]:
    return tuple(
        PoseBlock(first_index + i, tuple(float(v) for v in p))  # type: ignore[arg-type]
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

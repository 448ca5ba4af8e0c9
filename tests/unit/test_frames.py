"""conformance.protocol.frames: the decoder's builders make the objects the constructors make."""

from __future__ import annotations

import dataclasses
import struct

import pytest

from conformance.protocol import Action, Frame, PoseBlock, TransferType, frames, pose_blocks, request
from conformance.protocol.frames import new_frame, new_pose_block, new_pose_blocks

POSES = [(1.0, 2.0, 3.0, 4.0, 5.0, 6.0), (-1.5, 0.0, 2.5, 1e30, -1e-30, 7.0), (0.0,) * 6]


def _same(built: object, made: object) -> None:
    assert type(made) is type(built)
    assert made == built and hash(made) == hash(built) and repr(made) == repr(built)


def test_new_pose_block_is_a_pose_block() -> None:
    made = new_pose_block(3, POSES[0])
    _same(PoseBlock(3, POSES[0]), made)
    assert made.index == 3 and made.pose == POSES[0] and made.block_type == PoseBlock.block_type
    with pytest.raises(dataclasses.FrozenInstanceError):
        made.pose = POSES[1]  # type: ignore[misc]


def test_new_pose_blocks_reads_a_flat_struct_run() -> None:
    flat = struct.unpack(">" + "B6f" * 3, b"".join(struct.pack(">B6f", i, *p) for i, p in enumerate(POSES)))
    made = new_pose_blocks(flat, 3)
    assert type(made) is tuple and len(made) == 3
    assert [b.index for b in made] == [0, 1, 2]
    assert [b.pose for b in made] == [flat[7 * i + 1 : 7 * i + 7] for i in range(3)]
    for built, block in zip(pose_blocks(b.pose for b in made), made):
        _same(built, block)
    assert new_pose_blocks(flat, 0) == ()


def test_new_frame_is_a_frame_whose_check_does_not_count() -> None:
    blocks = pose_blocks(POSES[:2])
    built = request(Action.POSE, blocks, 7)
    made = new_frame(TransferType.ROBOT_TO_BOX, Action.POSE, blocks, 7, 0x1234)
    _same(Frame(TransferType.ROBOT_TO_BOX, Action.POSE, blocks, 7, 0x1234), made)
    assert made == built and hash(made) == hash(built) and made.check == 0x1234
    assert made.header == built.header and made.describe() == built.describe()
    with pytest.raises(dataclasses.FrozenInstanceError):
        made.error_code = 0  # type: ignore[misc]
    with pytest.raises(dataclasses.FrozenInstanceError):
        del made.blocks  # type: ignore[misc]


def test_the_setters_follow_the_fields_or_refuse() -> None:
    assert len(frames._slot_setters(PoseBlock, "index", "pose")) == 2
    with pytest.raises(TypeError, match="PoseBlock fields are"):
        frames._slot_setters(PoseBlock, "pose", "index")
    with pytest.raises(TypeError, match="Frame fields are"):
        frames._slot_setters(Frame, "transfer_type", "action", "blocks", "error_code")

"""Hypothesis strategies for the project's own tests: well-formed frames."""

from __future__ import annotations

from hypothesis import strategies as st

from conformance.protocol import (
    ANSWER_SHAPE,
    REQUEST_SHAPE,
    Action,
    BlockType,
    Frame,
    PoseBlock,
    ToleranceBlock,
    TransferType,
    ValueBlock,
)

# float32-representable values (so encode -> decode is exact); finite for strict profiles
f32 = st.floats(width=32, allow_nan=False, allow_infinity=False)
int32 = st.integers(-(2**31), 2**31 - 1)
error_codes = st.integers(0, 0xFFFF)


def _blocks(block_type: BlockType, count: int, first: int) -> st.SearchStrategy[tuple]:
    if block_type is BlockType.POSE:
        one = st.tuples(f32, f32, f32, f32, f32, f32)
        return st.lists(one, min_size=count, max_size=count).map(
            lambda poses: tuple(PoseBlock(first + i, p) for i, p in enumerate(poses))
        )
    if block_type is BlockType.TOLERANCE:
        return st.lists(f32, min_size=count, max_size=count).map(
            lambda ts: tuple(ToleranceBlock(first + i, t) for i, t in enumerate(ts))
        )
    if block_type is BlockType.VALUE:
        return st.lists(int32, min_size=count, max_size=count).map(
            lambda vs: tuple(ValueBlock(first + i, v) for i, v in enumerate(vs))
        )
    return st.just(())


@st.composite
def frames(draw: st.DrawFn, first_index: int = 0, max_blocks: int = 6, direction: TransferType | None = None) -> Frame:
    """Any well-formed frame: a request or an answer with the shape its action needs."""
    tt = direction if direction is not None else draw(st.sampled_from(list(TransferType)))
    shapes = REQUEST_SHAPE if tt is TransferType.ROBOT_TO_BOX else ANSWER_SHAPE
    action = draw(st.sampled_from(list(Action)))
    shape = shapes[action]
    count = draw(st.integers(shape.low, min(shape.high, max(shape.low, max_blocks))))
    blocks = draw(_blocks(shape.block_type, count, first_index))
    error = draw(error_codes) if tt is TransferType.BOX_TO_ROBOT else draw(st.sampled_from([0, 0, 0, 1, 0x1001]))
    if tt is TransferType.BOX_TO_ROBOT and action is Action.NONE:
        error = 0  # A4
    if tt is TransferType.BOX_TO_ROBOT and action is Action.VISION_RESULT and blocks[0].value in (0, 404):
        blocks = (ValueBlock(first_index, 1),)  # E3: 0 and 404 are never sent
    return Frame(tt, action, blocks, error)


def splits(data: bytes) -> st.SearchStrategy[list[bytes]]:
    """``data`` cut into consecutive non-empty pieces at arbitrary points."""
    if len(data) < 2:
        return st.just([data] if data else [])
    return st.sets(st.integers(1, len(data) - 1), max_size=min(20, len(data) - 1)).map(
        lambda cuts: [data[a:b] for a, b in zip([0, *sorted(cuts)], [*sorted(cuts), len(data)])]
    )

"""The table of multi-byte fields and the one-byte changes F4-02 and F7-05 send (protocol/field_bytes.py)."""

from __future__ import annotations

import pytest

from conformance.protocol import Action, Header, Profile, encode, parse_header, pose_blocks, request
from conformance.protocol.constants import CHECK_LEN, HEADER_FIELDS, MAX_FRAME_LEN, Transport
from conformance.protocol.field_bytes import MASKS, MULTI_BYTE_FIELDS, ByteChange, byte_changes, completed

POSE = request(Action.POSE, pose_blocks([(500.0, 0.0, 300.0, 180.0, 0.0, 90.0)]))


def test_the_table_is_the_layouts_multi_byte_fields_then_the_check_field() -> None:
    assert [f.name for f in MULTI_BYTE_FIELDS] == ["start_word", "version", "block_length", "error_code", "check"]
    for span in MULTI_BYTE_FIELDS[:-1]:
        assert (span.offset, span.width) == HEADER_FIELDS[span.name] and span.in_header
    check = MULTI_BYTE_FIELDS[-1]
    assert (check.offset, check.width, check.in_header) == (-CHECK_LEN, CHECK_LEN, False)
    assert check.start(39) == 37


def test_every_byte_of_every_field_is_changed_by_every_mask() -> None:
    changes = byte_changes()
    assert len(changes) == sum(f.width for f in MULTI_BYTE_FIELDS) * len(MASKS) == len(set(changes))
    assert {(c.field, c.byte) for c in changes} == {(f.name, b) for f in MULTI_BYTE_FIELDS for b in range(f.width)}
    assert byte_changes("version") == tuple(ByteChange("version", b, m) for b in (0, 1) for m in MASKS)


@pytest.mark.parametrize("order", ["big", "little"])
@pytest.mark.parametrize("change", byte_changes(), ids=lambda c: f"{c.field}-{c.byte}-{c.mask:02x}")
def test_a_change_alters_one_byte_of_its_field_and_nothing_else(order: str, change: ByteChange) -> None:
    profile = Profile(byte_order=order)
    transport = Transport.UDP if change.field == "check" else Transport.TCP
    good = encode(POSE, profile, transport)
    bad = change.apply(good, order)
    moved = [i for i in range(len(good)) if good[i] != bad[i]]
    span = change.span
    assert len(bad) == len(good) and len(moved) == 1
    assert span.start(len(good)) <= moved[0] < span.start(len(good)) + span.width
    if span.in_header:  # named by significance: the same field value under either byte order
        valid = getattr(POSE.header, change.field)
        assert getattr(parse_header(bad, profile), change.field) == change.value(valid) != valid


def test_the_low_byte_of_the_block_length_is_left_valid_by_one_change() -> None:
    """L = 0x0119: what a box reading only the low byte takes for 25."""
    change = ByteChange("block_length", 0, 0x01)
    bad = change.apply(encode(POSE))
    assert bad[8:10] == b"\x01\x19" and change.value(25) == 0x0119
    assert "0x0019 -> 0x0119" in change.describe(25)
    assert ByteChange("block_length", 0, 0x01).apply(encode(POSE, Profile(byte_order="little")), "little")[8:10] \
        == b"\x19\x01"


def test_completed_pads_to_the_announced_frame_only_when_a_legal_header_could_announce_it() -> None:
    frame = ByteChange("block_length", 0, 0x01).apply(encode(POSE))
    padded = completed(frame, 12 + 0x0119 + 2)
    assert padded[: len(frame)] == frame and len(padded) == 295 and not any(padded[len(frame):])
    assert completed(frame, 12 + 0xFF19 + 2) == frame  # beyond MAX_FRAME_LEN: no legal header announces it
    assert completed(frame, 38) == frame and completed(frame, MAX_FRAME_LEN + 1) == frame
    assert parse_header(padded) == Header(action=Action.POSE, block_type=1, block_count=1, block_length=0x0119)

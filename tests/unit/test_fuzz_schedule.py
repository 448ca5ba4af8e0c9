"""The boundary-first schedule and the coverage of the input space (conformance/fuzz/schedule.py, input_coverage.py)."""

from __future__ import annotations

import struct

import pytest

from conformance.fuzz.input_coverage import (
    EDGES_U8,
    EDGES_U16,
    SIZE_POINTS,
    VALUE_CLASSES,
    Coverage,
    float_class,
    size_point,
)
from conformance.fuzz.schedule import FLOAT_SPECIALS, GARBAGE_SIZES, Schedule, boundary_counts
from conformance.fuzz.strategies import BLOCK_ACTIONS, Strategies, _recount
from conformance.protocol import (
    DEFAULT_PROFILE,
    MAX_FRAME_LEN,
    Action,
    Header,
    Profile,
    ProtocolError,
    Transport,
    parse_frame,
)


def schedule(profile: Profile = DEFAULT_PROFILE, udp: bool = True) -> list:
    return list(Schedule(Strategies(profile, extension=True, udp=udp)))


def test_every_block_count_of_every_block_action_is_a_well_formed_request_with_correct_indexes() -> None:
    counts: dict[int, set[int]] = {int(a): set() for a in BLOCK_ACTIONS}
    for case in schedule():
        if case.kind == "valid-count":
            frame = parse_frame(case.data, DEFAULT_PROFILE, Transport.TCP)  # raises on a bad index or shape
            assert case.valid and not case.filler
            assert [b.index for b in frame.blocks] == list(range(len(frame.blocks)))
            counts[int(frame.action)].add(len(frame.blocks))
    assert all(c == set(range(1, 256)) for c in counts.values())


def test_the_counts_come_boundaries_first() -> None:
    order = boundary_counts()
    assert sorted(order) == list(range(1, 256))
    assert order[:9] == [1, 2, 3, 4, 5, 7, 8, 9, 15] and 255 in order[:30] and 128 in order[:30]


def test_a_campaign_s_schedule_covers_the_whole_space_and_the_small_groups_come_first() -> None:
    cases = schedule()
    cov = Coverage(DEFAULT_PROFILE)
    for case in cases:
        cov.observe(case)
    assert cov.fractions() == {"counts": 1.0, "fields": 1.0, "values": 1.0, "sizes": 1.0}
    first = Coverage(DEFAULT_PROFILE)
    for case in cases[:900]:  # float classes and sizes are reached early, before the counts are done
        first.observe(case)
    assert first.fractions()["values"] == 1.0 and first.fractions()["sizes"] == 1.0
    assert {c.kind for c in cases[:10]} >= {"edge-start_word", "edge-float", "edge-garbage", "valid-count"}


def test_field_values_floats_and_sizes_of_the_schedule() -> None:
    cases = schedule()
    errors = {int.from_bytes(c.data[10:12], "big") for c in cases if c.kind == "edge-error_code"}
    assert {1, 0x7FFF, 0x8000, 0xFFFF} <= errors
    words = {c.data[13:17] for c in cases if c.kind == "edge-float"}
    assert {struct.pack(">I", b) for b in FLOAT_SPECIALS} <= words
    sizes = {len(c.data) for c in cases if c.kind == "edge-garbage"}
    assert sizes == set(GARBAGE_SIZES) and max(sizes) > MAX_FRAME_LEN
    assert {c.kind for c in cases if c.transport is Transport.UDP} == {"F7-valid", "F7-crc"}
    splits = [c for c in cases if c.kind == "R3-split"]
    assert {c.splits[0] for c in splits} >= set(range(1, 39)) and max(c.gap_s for c in splits) >= 0.1


def test_the_schedule_follows_the_profile() -> None:
    little = DEFAULT_PROFILE.replace(first_index=1, byte_order="little", float_byte_order="little")
    for case in schedule(little, udp=False):
        if case.kind == "valid-count":
            assert parse_frame(case.data, little, Transport.TCP).blocks[0].index == 1


@pytest.mark.parametrize(("bits", "cls"), [
    (0x00000000, "zero"), (0x80000000, "-zero"), (0x00000001, "subnormal"), (0x807FFFFF, "-subnormal"),
    (0x00800000, "min-normal"), (0x3F800000, "normal"), (0x7149F2CA, "huge"), (0x7F7FFFFF, "max-finite"),
    (0xFF7FFFFF, "-max-finite"), (0x7F800000, "inf"), (0xFF800000, "-inf"), (0x7FC00000, "qnan"),
    (0x7F800001, "snan"), (0xFFC00000, "-nan"),
])
def test_float_classes(bits: int, cls: str) -> None:
    assert float_class(bits) == cls and cls in VALUE_CLASSES


def test_edges_and_size_points() -> None:
    assert {0, 1, 2, 3, 4, 5, 7, 8, 9, 127, 128, 129, 254, 255} <= set(EDGES_U8) and max(EDGES_U8) == 255
    assert {0x7FFF, 0x8000, 0x8001, 0xFFFE, 0xFFFF} <= set(EDGES_U16)
    assert size_point(MAX_FRAME_LEN) == "max-frame" and size_point(1) == "<2" and size_point(14) == "<16"
    assert size_point(10**6) == SIZE_POINTS[16]


def test_a_mutated_count_byte_gives_a_well_formed_frame_of_that_count() -> None:
    s = Strategies(DEFAULT_PROFILE)
    header = Header(action=Action.TOLERANCE, block_type=2, block_count=2, block_length=5)
    body = s.blocks(2, 2, bytes(8))
    data = bytearray(s.raw(header, body))
    data[7] = 7
    rebuilt = _recount(s, header, body, bytes(data))
    assert rebuilt is not None
    frame = parse_frame(rebuilt, DEFAULT_PROFILE, Transport.TCP)
    assert [b.index for b in frame.blocks] == list(range(7))
    data[6] = 1  # another header byte changed too: not a count mutation
    assert _recount(s, header, body, bytes(data)) is None


def test_one_wrong_index_where_a_counter_wraps_comes_first() -> None:
    """B3 edges: a wrong index at blocks 1, 2, 17, 129 and 255 of every block action, in the first cases
    (a box counting indexes in 4 bits takes a wrong index at block 17), each a parse error (never 0000)."""
    cases = schedule(Profile(first_index=1))
    at = [n for n, c in enumerate(cases) if c.kind == "edge-index"]
    wrong = [cases[n] for n in at]
    assert len(wrong) == 5 * len(BLOCK_ACTIONS) and max(at) < 7 * len(wrong)  # taken in turn with 6 other groups
    for case in wrong:
        with pytest.raises(ProtocolError) as bad:
            parse_frame(case.data, Profile(first_index=1), Transport.TCP)
        assert bad.value.clause == "B3" and not case.valid
    at_17 = [c for c in wrong if c.data[7] == 17]
    assert {c.data[12 + 16 * (25 if c.data[6] == 1 else 5)] for c in at_17} == {(1 + 16) & 0x0F}

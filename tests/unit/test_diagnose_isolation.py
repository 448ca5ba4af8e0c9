"""Isolation (conformance/diagnose/differences.py, dimensions.py): the pure parts — the nearest valid request,
where a byte lies, Zeller's ddmin, float classes, which CRC a check field holds, the bound a bisection found."""

from __future__ import annotations

import struct

import crcmod.predefined
import pytest

from conformance.diagnose import isolation_titles as T
from conformance.diagnose.differences import (
    Place,
    applied,
    ddmin,
    differing,
    float_class,
    low_high,
    nearest_valid,
    place,
    units,
)
from conformance.diagnose.dimensions import _knee, _round, crc_of
from conformance.protocol import Action, PoseBlock, Profile, codec_for, encode, request

CODEC = codec_for(Profile())
POSE = (1.0, 2.0, 3.0, 4.0, 5.0, 6.0)


def pose(*indexes: int) -> bytes:
    return encode(request(Action.POSE, [PoseBlock(i, POSE) for i in indexes]))


def test_the_nearest_valid_request_fixes_each_field_and_keeps_the_rest() -> None:
    none = encode(request(Action.NONE))
    bad = bytearray(none)
    bad[2:4] = b"\x01\x00"  # version 01 00
    assert nearest_valid(bytes(bad), CODEC) == none and differing(bytes(bad), none) == [2, 3]
    two = pose(0, 1)
    gap = bytearray(two)
    gap[12 + 25] = 2  # indexes 00, 02
    assert nearest_valid(bytes(gap), CODEC) == two
    wrong_length = bytearray(two)
    wrong_length[8:10] = b"\x19\x00"  # block length 19 00, blocks still 25 bytes
    assert differing(bytes(wrong_length), nearest_valid(bytes(wrong_length), CODEC) or b"") == [8, 9]
    nan = bytearray(pose(0))
    nan[13:17] = b"\x7f\xc0\x00\x00"
    fixed = nearest_valid(bytes(nan), CODEC)
    assert fixed is not None and fixed[13:17] == struct.pack(">f", 1.0) and CODEC.parse(fixed)
    unknown = bytearray(none)
    unknown[5] = 0x30  # an unknown action without blocks: nearest to NONE
    assert nearest_valid(bytes(unknown), CODEC) == none
    assert nearest_valid(none[:10], CODEC) is None  # shorter than any frame
    assert nearest_valid(pose(0)[:-3], CODEC) is None  # no request of that length (a pose cut short)


def test_a_first_index_of_one_is_the_profile_s() -> None:
    codec = codec_for(Profile(first_index=1))
    wrong = pose(0)
    fixed = nearest_valid(wrong, codec)
    assert fixed is not None and fixed[12] == 1 and differing(wrong, fixed) == [12]


def test_where_a_byte_lies() -> None:
    n = len(pose(0, 1))
    assert place(3, n, 25) == Place("version") and place(9, n, 25) == Place("block_length")
    assert place(12, n, 25) == Place("index", 1) and place(37, n, 25) == Place("index", 2)
    assert place(13, n, 25) == Place("value", 1, 0) and place(36, n, 25) == Place("value", 1, 5)
    assert place(n - 1, n, 25) == Place("check") and place(13, 14, 0) == Place("check")
    # bytes of one field are one unit: the version's two bytes, one float's four
    assert units([2, 3, 13, 14, 37], n, 25) == [[2, 3], [13, 14], [37]]
    assert low_high("version", "big") == (3, 2) and low_high("version", "little") == (2, 3)
    assert low_high("action", "big") is None


def test_ddmin_finds_a_one_minimal_failing_subset() -> None:
    calls: list[list[int]] = []

    def fails(subset: list[int]) -> bool:
        calls.append(subset)
        return 3 in subset and 7 in subset

    assert sorted(ddmin(list(range(10)), fails, max_tests=64)) == [3, 7]
    assert ddmin([5], fails) == [5]  # nothing to narrow
    assert ddmin([1, 2, 3, 4], lambda s: None) == [1, 2, 3, 4]  # out of time: what is known to fail
    assert len(ddmin(list(range(64)), lambda s: 9 in s, max_tests=4)) > 1  # the budget bounds the search


def test_applied_writes_only_the_chosen_differences() -> None:
    passing, failing = b"\x00\x01\x02\x03", b"\x09\x01\x08\x07"
    assert applied(passing, failing, [0, 3]) == b"\x09\x01\x02\x07"


@pytest.mark.parametrize("raw, kind", [("7fc00000", "NaN"), ("7f800000", "+infinity"), ("ff800000", "-infinity"),
                                       ("80000000", "negative zero"), ("00000000", "zero"), ("0000807f", "subnormal"),
                                       ("3f800000", "")])
def test_float_classes(raw: str, kind: str) -> None:
    assert float_class(bytes.fromhex(raw)) == kind


def test_the_crc_in_a_check_field_is_named_with_its_byte_order() -> None:
    body = bytes.fromhex("fefe00011000000000000000")
    modbus = crcmod.predefined.mkPredefinedCrcFun("modbus")(body)
    assert crc_of(body, modbus.to_bytes(2, "big")) == ("CRC-16/MODBUS", "big")
    assert crc_of(body, modbus.to_bytes(2, "little")) == ("CRC-16/MODBUS", "little")
    arc = crcmod.predefined.mkPredefinedCrcFun("crc-16")(body)
    assert crc_of(body, arc.to_bytes(2, "big")) == ("CRC-16/ARC", "big")
    assert crc_of(body, b"\x12\x34") is None or crc_of(body, b"\x12\x34") != ("CRC-16/MODBUS", "big")


def test_a_bound_found_by_bisection_is_written_as_a_firmware_would() -> None:
    assert _round(9.9996, 10.0003) == 10
    assert _round(127.4, 128.2) == 128
    assert _round(0.2499, 0.2502) == 0.25


def test_the_knee_of_a_latency_that_grows_after_request_100() -> None:
    times = [1.0] * 100 + [1.0 + k for k in range(1, 121)]
    assert abs(_knee(times, 1.0) - 101) <= 2
    assert _knee([1.0] * 50, 1.0) == 0


def test_titles_name_the_field_what_the_box_does_and_the_fix() -> None:
    assert T.unchecked("version", ["00 02", "01 00"], 0).startswith(
        "Does not check the version field: answers 0000 to NONE (00) with the version field 00 02 (and 01 00)")
    assert "reads only the low byte" in T.one_byte("version", True, "01 01", 0).lower()
    assert "high byte ignored" in T.one_byte("version", True, "01 01", 0)
    assert "from the block type, not the header" in T.length_from_type("00 05", 0x23, 25)
    assert T.index_unchecked(2, 2, 1, 0, 0x23).startswith(
        "Does not check block indexes: answers 0000 to pose (23) with index 02 at the 2nd block (expected 01)")
    assert "several frames" in T.coalesced(1, 2) and "CycleOff (02)" in T.closes_after("CycleOff (02)")
    assert "result request (27)" in T.no_answer(0x27)
    assert "little-endian" in T.float_order("little", "NaN", 0x23, True)


def test_a_death_is_named_with_the_input_it_followed() -> None:
    from conformance.diagnose import death_inputs
    from conformance.model.verdicts import CaseResult, Level, RootCause, Verdict

    head = bytes.fromhex("fefe000101230 1ffffff0000".replace(" ", ""))
    assert death_inputs.oversize(b"\x00\x01" + head) == (255, 0xFFFF)
    assert death_inputs.oversize(pose(0)) is None
    killer = CaseResult("R5-02", "oversize", ("R5",), Level.MUST, Verdict.FAIL, sent_hex=head.hex(" "))
    leak = RootCause("RC1", ("S5", "R2"), "The box stops accepting connections after the suite has opened 9",
                     "evidence", ["R5-02"], kind="connection-leak", confirmed=True)
    unconfirmed = RootCause("RC2", ("R2",), "unconfirmed: …", "evidence", ["R5-02"], kind="dead-after-input",
                            confirmed=False)
    death_inputs.name([leak, unconfirmed], [killer])
    assert leak.title.startswith("Stops accepting new connections after a header announcing 255 × 65535 block bytes")
    assert "length beyond the largest legal frame" in leak.title and "still served" in leak.title
    assert unconfirmed.title == "unconfirmed: …"  # only what the phase confirmed is retitled


def test_a_start_word_read_from_one_byte_is_named_by_its_first_and_second_byte() -> None:
    from conformance.diagnose import isolation_titles

    title = isolation_titles.one_byte("start_word", False, "fe ff", 0x23)
    assert title.startswith("Checks only the first byte of the start word") and "second byte ignored" in title
    assert "fe ff" in title and "F1" in title
    assert "second byte of the start word" in isolation_titles.one_byte("start_word", True, "ff fe", 0x23)

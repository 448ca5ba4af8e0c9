"""conformance.protocol.codec: encode, parse_frame, decode_datagram."""

from __future__ import annotations

import math
import struct

import pytest
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

from conformance.protocol import (
    Action,
    BlockIndexError,
    CheckError,
    DirectionError,
    FloatError,
    Frame,
    Header,
    LengthError,
    PoseBlock,
    Profile,
    ProtocolError,
    ShapeError,
    StartWordError,
    TcpCheckPolicy,
    ToleranceBlock,
    TransferType,
    Transport,
    UnknownActionError,
    ValueBlock,
    VersionError,
    action_name,
    answer,
    codec_for,
    decode_datagram,
    encode,
    encode_raw,
    encode_udp,
    parse_frame,
    pose_blocks,
    request,
    tolerance_blocks,
    value_blocks,
)
from tests.strategies import frames

R2B, B2R = TransferType.ROBOT_TO_BOX, TransferType.BOX_TO_ROBOT
POSE_HEX = (
    "fefe0001012301010019"
    "0000"
    "00" "3f800000" "40000000" "40400000" "40800000" "40a00000" "40c00000"
    "0000"
)


def test_pose_request_bytes_match_the_layout_by_hand() -> None:
    frame = request(Action.POSE, pose_blocks([(1, 2, 3, 4, 5, 6)]))
    assert encode(frame).hex() == POSE_HEX
    assert len(encode(frame)) == 12 + 25 + 2  # F5


def test_answer_bytes_match_the_revision_diagram() -> None:
    # PROTOCOL.md A2: FE FE|00 01|10|23|00|00|00 00|00 00|00 00
    assert encode(answer(Action.POSE)).hex(" ") == "fe fe 00 01 10 23 00 00 00 00 00 00 00 00"


def test_udp_check_is_modbus_crc_big_endian() -> None:
    frame = answer(Action.CYCLE_ON)
    data = encode_udp(frame)
    body = data[:-2]
    assert data[-2:] == Profile().check_bytes(body)
    # CRC-16/MODBUS of the check string is 0x4B37 (F7)
    assert Profile().crc_of(b"123456789") == 0x4B37
    little = encode_udp(frame, Profile(crc_byte_order="little"))
    assert little[-2:] == data[-2:][::-1]


@pytest.mark.parametrize(("name", "check"), [("modbus", 0x4B37), ("xmodem", 0x31C3), ("kermit", 0x2189), ("x-25", 0x906E)])
def test_crc_algorithms_have_their_published_check_values(name: str, check: int) -> None:
    assert Profile(crc=name).crc_of(b"123456789") == check


def test_parse_returns_typed_enums_and_blocks() -> None:
    frame = parse_frame(bytes.fromhex(POSE_HEX), expect=R2B)
    assert frame.transfer_type is R2B and frame.action is Action.POSE
    assert frame.blocks == (PoseBlock(0, (1.0, 2.0, 3.0, 4.0, 5.0, 6.0)),)
    assert frame.header == Header(0xFEFE, 1, 0x01, 0x23, 0x01, 1, 25, 0)


def _mutate(hexstr: str, offset: int, value: bytes) -> bytes:
    data = bytearray.fromhex(hexstr)
    data[offset : offset + len(value)] = value
    return bytes(data)


@pytest.mark.parametrize(
    ("data", "error", "clause", "offset"),
    [
        (_mutate(POSE_HEX, 0, b"\xfe\xff"), StartWordError, "F1", 0),
        (_mutate(POSE_HEX, 2, b"\x00\x02"), VersionError, "F2", 2),
        (_mutate(POSE_HEX, 4, b"\x10"), DirectionError, "F3", 4),
        (_mutate(POSE_HEX, 4, b"\x02"), DirectionError, "F3", 4),
        (_mutate(POSE_HEX, 5, b"\x28"), UnknownActionError, "A5", 5),
        (_mutate(POSE_HEX, 6, b"\x02"), ShapeError, "B5", 6),
        (_mutate(POSE_HEX, 12, b"\x01"), BlockIndexError, "B3", 12),
        (_mutate(POSE_HEX, 13, struct.pack(">f", math.nan)), FloatError, "B4", 13),
        (_mutate(POSE_HEX, 17, struct.pack(">f", -math.inf)), FloatError, "B4", 13),
        (bytes.fromhex(POSE_HEX)[:-1], LengthError, "F5", 38),
        (bytes.fromhex(POSE_HEX) + b"\x00", LengthError, "F5", 39),
        (bytes.fromhex(POSE_HEX)[:13], LengthError, "F5", 13),
    ],
)
def test_each_broken_clause_is_named(data: bytes, error: type, clause: str, offset: int) -> None:
    with pytest.raises(error) as info:
        parse_frame(data, expect=R2B)
    assert info.value.clause == clause
    assert info.value.offset == offset
    assert info.value.raw == data
    assert str(info.value).startswith(f"[{clause}]")
    if len(data) >= 12:
        assert info.value.header is not None and info.value.header.start_word == int.from_bytes(data[:2], "big")


def test_block_length_not_matching_the_type_names_the_block_clause() -> None:
    hdr = Header(action=Action.TOLERANCE, block_type=0x02, block_count=1, block_length=25)
    data = encode_raw(hdr, b"\x00" * 25)
    with pytest.raises(ShapeError) as info:
        parse_frame(data)
    assert info.value.clause == "B2"
    hdr = Header(action=Action.PROG_IDX, block_type=0x03, block_count=1, block_length=4)
    with pytest.raises(ShapeError) as info:
        parse_frame(encode_raw(hdr, b"\x00" * 4))
    assert info.value.clause == "E1"


@pytest.mark.parametrize(
    ("frame_header", "body", "clause"),
    [
        (Header(action=Action.POSE), b"", "B5"),  # a pose request needs N >= 1
        (Header(action=Action.CYCLE_ON, block_type=1, block_count=1, block_length=25), bytes(25), "B5"),
        (Header(action=Action.NONE, block_length=25), b"", "B5"),  # type 00 needs L = 0
        (Header(action=Action.PROG_IDX), b"", "E2"),
        (Header(action=Action.PROG_IDX, block_type=3, block_count=2, block_length=5), bytes([0, 0, 0, 0, 1, 1, 0, 0, 0, 2]), "E2"),
        (Header(action=Action.VISION_RESULT, block_type=3, block_count=1, block_length=5), bytes(5), "E3"),
        (Header(transfer_type=0x10, action=Action.POSE, block_type=1, block_count=1, block_length=25), bytes(25), "A2"),
        (Header(transfer_type=0x10, action=Action.VISION_RESULT), b"", "E3"),
    ],
)
def test_shapes_by_action_and_direction(frame_header: Header, body: bytes, clause: str) -> None:
    with pytest.raises(ShapeError) as info:
        parse_frame(encode_raw(frame_header, body))
    assert info.value.clause == clause


def test_answers_to_extension_actions_carry_one_value_block() -> None:
    for action in (Action.PROG_IDX, Action.VISION_RESULT):
        frame = answer(action, blocks=value_blocks([409]))
        assert parse_frame(encode(frame), expect=B2R) == frame


def test_value_blocks_are_signed_int32() -> None:
    frame = request(Action.PROG_IDX, value_blocks([-2]))
    assert encode(frame)[12:17] == b"\x00\xff\xff\xff\xfe"
    assert parse_frame(encode(frame)).blocks == (ValueBlock(0, -2),)


def test_tcp_check_policies() -> None:
    frame = request(Action.CYCLE_ON)
    with_crc = encode_udp(frame)  # same body, CRC in the check field
    wrong = with_crc[:-2] + b"\x12\x34"
    assert parse_frame(with_crc).check == int.from_bytes(with_crc[-2:], "big")  # default zero-or-crc
    with pytest.raises(CheckError) as info:
        parse_frame(wrong)
    assert info.value.clause == "F6"
    strict_zero = Profile(tcp_check=TcpCheckPolicy.ZERO)
    with pytest.raises(CheckError):
        parse_frame(with_crc, strict_zero)
    assert parse_frame(wrong, Profile(tcp_check="ignore")) == frame


def test_udp_crc_mismatch_is_f7_and_checked_before_the_header() -> None:
    data = bytearray(encode_udp(request(Action.POSE, pose_blocks([(0, 0, 0, 0, 0, 0)]))))
    data[-1] ^= 0xFF
    with pytest.raises(CheckError) as info:
        decode_datagram(bytes(data))
    assert info.value.clause == "F7" and info.value.offset == len(data) - 2
    with pytest.raises(LengthError):
        decode_datagram(bytes(data) + b"\x00")  # R7: not exactly one frame


def test_first_index_profile_and_lenient_mode() -> None:
    one = request(Action.POSE, pose_blocks([(1, 1, 1, 1, 1, 1)] * 2, first_index=1))
    data = encode(one)
    with pytest.raises(BlockIndexError):
        parse_frame(data)
    assert parse_frame(data, Profile(first_index=1)) == one
    assert parse_frame(data, Profile(strict=False)) == one
    zero = encode(request(Action.POSE, pose_blocks([(1, 1, 1, 1, 1, 1)] * 2)))
    with pytest.raises(BlockIndexError):
        parse_frame(zero, Profile(first_index=1))


def test_lenient_accepts_non_finite_floats() -> None:
    frame = request(Action.TOLERANCE, [ToleranceBlock(0, math.inf)])
    data = encode(frame)
    with pytest.raises(FloatError):
        parse_frame(data)
    assert parse_frame(data, Profile(strict=False)).blocks[0].tolerance == math.inf


def test_little_endian_profile_round_trips_and_differs_on_the_wire() -> None:
    prof = Profile(byte_order="little", float_byte_order="little")
    frame = request(Action.TOLERANCE, tolerance_blocks([0.5, 1.5]))
    data = encode(frame, prof)
    assert data[8:10] == b"\x05\x00" and data != encode(frame)
    assert parse_frame(data, prof) == frame
    with pytest.raises(ProtocolError):
        parse_frame(data)


def test_encode_rejects_frames_it_cannot_represent() -> None:
    with pytest.raises(ValueError, match="one type"):
        encode(Frame(R2B, Action.POSE, (PoseBlock(0, (0,) * 6), ToleranceBlock(1, 0.0))))  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="at most 255"):
        encode(request(Action.TOLERANCE, tolerance_blocks([0.0] * 256)))
    with pytest.raises(ValueError, match="out of range"):
        encode(request(Action.PROG_IDX, [ValueBlock(0, 2**31)]))
    with pytest.raises(ValueError, match="6 values"):
        encode(request(Action.POSE, [PoseBlock(0, (1.0, 2.0))]))  # type: ignore[arg-type]


# -- properties ---------------------------------------------------------------------------

profiles = st.builds(
    Profile,
    crc=st.sampled_from(["modbus", "xmodem", "kermit", "crc-16", "x-25"]),
    crc_byte_order=st.sampled_from(["big", "little"]),
    first_index=st.sampled_from([0, 1]),
    byte_order=st.sampled_from(["big", "little"]),
    float_byte_order=st.sampled_from(["big", "little"]),
)


@given(st.data(), profiles, st.sampled_from(list(Transport)))
def test_round_trip_every_frame(data: st.DataObject, profile: Profile, transport: Transport) -> None:
    frame = data.draw(frames(first_index=profile.first_index))
    wire = encode(frame, profile, transport)
    assert len(wire) == 12 + len(frame.blocks) * frame.block_length + 2
    assert parse_frame(wire, profile, transport, frame.transfer_type) == frame


@settings(suppress_health_check=[HealthCheck.too_slow])
@given(st.binary(max_size=200), st.sampled_from(list(Transport)))
@example(bytes.fromhex(POSE_HEX), Transport.TCP)
def test_arbitrary_bytes_give_a_frame_or_a_typed_error(data: bytes, transport: Transport) -> None:
    try:
        frame = parse_frame(data, transport=transport)
    except ProtocolError as exc:
        assert exc.clause[0] in "FBAE" and 0 <= exc.offset <= len(data)
        assert exc.raw == data
    else:
        assert isinstance(frame, Frame)


@st.composite
def mutated(draw: st.DrawFn) -> bytes:
    """A valid frame with a few bytes overwritten: reaches every check."""
    wire = bytearray(encode(draw(frames())))
    for _ in range(draw(st.integers(0, 3))):
        wire[draw(st.integers(0, len(wire) - 1))] = draw(st.integers(0, 255))
    return bytes(wire)


@given(st.one_of(mutated(), st.binary(max_size=80)), st.sampled_from([None, R2B, B2R]), st.booleans())
def test_fast_path_agrees_with_the_reference_parser(data: bytes, expect: TransferType | None, strict: bool) -> None:
    codec = codec_for(Profile(strict=strict))

    def outcome(parse):  # type: ignore[no-untyped-def]
        try:
            return parse(data, Transport.TCP, expect)
        except ProtocolError as exc:
            return (type(exc), exc.clause, exc.offset, str(exc))

    assert outcome(codec.parse) == outcome(codec.parse_checked)


@given(frames())
def test_header_property_matches_the_bytes(frame: Frame) -> None:
    wire = encode(frame)
    assert encode_raw(frame.header, wire[12:-2]) == wire
    assert wire[7] == len(frame.blocks) and int.from_bytes(wire[8:10], "big") == frame.block_length


def test_fast_built_objects_are_ordinary_frozen_instances() -> None:
    """The hot paths build frames without the dataclass constructor: the objects must be
    real, equal, hashable and frozen all the same."""
    import dataclasses

    for poses in ([(1, 2, 3, 4, 5, 6)], [(1, 2, 3, 4, 5, 6)] * 3):
        built = request(Action.POSE, pose_blocks(poses))
        parsed = parse_frame(encode(built))
        assert type(parsed) is Frame and type(parsed.blocks[0]) is PoseBlock
        assert parsed == built and hash(parsed) == hash(built) and repr(parsed) == repr(built)
        with pytest.raises(dataclasses.FrozenInstanceError):
            parsed.error_code = 1  # type: ignore[misc]
        with pytest.raises(dataclasses.FrozenInstanceError):
            parsed.blocks[0].index = 9  # type: ignore[misc]


def test_action_name_names_known_actions_hex_for_others_and_says_what_none_means():
    assert action_name(0x23) == "POSE" and action_name(Action.VISION_RESULT) == "VISION_RESULT"
    assert action_name(0x7F) == "0x7F"
    assert action_name(None) == "bytes that are not a request" and action_name(None, "-") == "-"


def test_float32_bit_patterns_are_independent_of_byte_order() -> None:
    from conformance.protocol.constants import f32_bits, f32_of_bits

    assert f32_bits(1.0) == 0x3F800000 and f32_bits(-0.0) == 0x80000000 and f32_bits(-2.5) == 0xC0200000
    for bits in (0x00000001, 0x007FFFFF, 0x7F7FFFFF, 0xFF7FFFFF, 0x49742400):
        assert f32_bits(f32_of_bits(bits)) == bits

"""conformance.protocol.stream: the TCP stream decoder, fed whole, byte by byte and coalesced."""

from __future__ import annotations

import pytest
from hypothesis import given
from hypothesis import strategies as st

from conformance.protocol import (
    CLOSED,
    MAX_FRAME_LEN,
    NEED_DATA,
    Action,
    BlockIndexError,
    DirectionError,
    Frame,
    Header,
    LengthError,
    Profile,
    ProtocolError,
    ShapeError,
    StartWordError,
    StreamDecoder,
    TcpCheckPolicy,
    TransferType,
    UnknownActionError,
    VersionError,
    answer,
    encode,
    encode_raw,
    pose_blocks,
    request,
)
from tests.strategies import frames, splits

POSE = request(Action.POSE, pose_blocks([(1, 2, 3, 4, 5, 6)]))
CYCLE_ON = request(Action.CYCLE_ON)
ZERO_CHECK = Profile(tcp_check=TcpCheckPolicy.ZERO)


def drain(decoder: StreamDecoder, pieces: list[bytes], eof: bool = False) -> list:
    out: list = []
    for piece in pieces:
        out += decoder.feed(piece)
    if eof:
        out += decoder.feed(b"")
    return out


def test_whole_byte_by_byte_and_coalesced_agree() -> None:
    wire = encode(POSE) + encode(CYCLE_ON) + encode(POSE)
    whole = StreamDecoder().feed(wire)
    single = drain(StreamDecoder(), [wire[i : i + 1] for i in range(len(wire))])
    assert whole == single == [POSE, CYCLE_ON, POSE]


def test_need_data_until_the_frame_is_complete_then_closed() -> None:
    dec = StreamDecoder()
    wire = encode(POSE)
    dec.receive_data(wire[:20])
    assert dec.next_event() is NEED_DATA and dec.buffered == 20
    dec.receive_data(wire[20:])
    assert dec.next_event() == POSE
    assert dec.next_event() is NEED_DATA
    dec.receive_data(b"")
    assert dec.next_event() is CLOSED and dec.eof
    with pytest.raises(RuntimeError):
        dec.receive_data(b"x")


def test_garbage_is_reported_once_and_the_stream_resynchronises() -> None:
    events = StreamDecoder().feed(b"hello world" + encode(POSE))
    assert isinstance(events[0], StartWordError)
    assert events[0].raw == b"hello world" and events[0].offset == 0
    assert events[1:] == [POSE]


def test_a_lone_fe_waits_for_the_next_byte() -> None:
    dec = StreamDecoder()
    events = dec.feed(b"\x00\xfe")
    assert [(type(e), e.raw) for e in events] == [(StartWordError, b"\x00")]
    assert dec.buffered == 1  # the FE may start a frame
    assert dec.feed(encode(POSE)[1:]) == [POSE]


def test_oversized_announcement_is_rejected_without_waiting() -> None:
    header = encode_raw(Header(action=Action.POSE, block_type=1, block_count=255, block_length=65535))[:12]
    dec = StreamDecoder()
    events = dec.feed(header + b"\x01\x02\x03" + encode(POSE))
    # the header names what makes the announcement illegal: L=65535 for a pose block (B1)
    assert isinstance(events[0], ShapeError) and events[0].clause == "B1"
    assert events[0].raw == header + b"\x01\x02\x03"
    assert events[0].header is not None and events[0].header.block_length == 65535
    assert events[-1] == POSE
    assert dec.buffered == 0


def test_oversized_announcement_with_an_unknown_action_is_a5() -> None:
    header = encode_raw(Header(action=0x99, block_type=1, block_count=255, block_length=65535))[:12]
    events = StreamDecoder().feed(header + encode(CYCLE_ON))
    assert [type(e) for e in events] == [UnknownActionError, Frame]


def test_the_decoder_never_waits_for_more_than_the_largest_frame() -> None:
    dec = StreamDecoder()
    dec.receive_data(encode_raw(Header(action=Action.POSE, block_type=1, block_count=255, block_length=25))[:12])
    sent = 12
    while dec.next_event() is NEED_DATA:
        dec.receive_data(b"\x00" * 100)
        sent += 100
        assert sent <= MAX_FRAME_LEN + 100
    assert sent >= MAX_FRAME_LEN


def test_wrong_version_skips_to_the_next_start_word() -> None:
    bad = bytearray(encode(POSE))
    bad[3] = 2
    events = StreamDecoder().feed(bytes(bad) + encode(CYCLE_ON))
    assert isinstance(events[0], VersionError) and events[0].raw == bytes(bad)
    assert events[1:] == [CYCLE_ON]


def test_a_malformed_frame_is_one_event_and_keeps_framing() -> None:
    bad = bytearray(encode(request(Action.POSE, pose_blocks([(0,) * 6] * 2))))
    bad[12 + 25] = 7  # second index
    events = StreamDecoder().feed(bytes(bad) + encode(POSE))
    assert isinstance(events[0], BlockIndexError) and events[0].offset == 37
    assert events[0].header is not None and events[0].header.action == Action.POSE
    assert events[1] == POSE


def test_error_offsets_count_from_the_start_of_the_stream() -> None:
    bad = bytearray(encode(POSE))
    bad[12] = 3
    events = StreamDecoder().feed(encode(CYCLE_ON) + bytes(bad))
    assert events[1].offset == 14 + 12


def test_truncated_frame_at_end_of_stream() -> None:
    dec = StreamDecoder()
    events = drain(dec, [encode(POSE)[:30]], eof=True)
    assert len(events) == 1 and isinstance(events[0], LengthError) and events[0].raw == encode(POSE)[:30]
    assert dec.next_event() is CLOSED


def test_direction_is_checked_for_the_expected_side() -> None:
    box_side = StreamDecoder(expect=TransferType.ROBOT_TO_BOX)
    robot_side = StreamDecoder(expect=TransferType.BOX_TO_ROBOT)
    wire = encode(answer(Action.POSE))
    assert isinstance(box_side.feed(wire)[0], DirectionError)
    assert robot_side.feed(wire) == [answer(Action.POSE)]


def _accounted(events: list) -> bytes:
    """Every event's bytes, in order: frames re-encoded, errors as their raw bytes."""
    return b"".join(e.raw if isinstance(e, ProtocolError) else encode(e, ZERO_CHECK) for e in events)


@given(st.lists(frames(), max_size=5), st.data())
def test_any_split_gives_the_same_frames(frame_list: list[Frame], data: st.DataObject) -> None:
    wire = b"".join(encode(f) for f in frame_list)
    pieces = data.draw(splits(wire))
    assert drain(StreamDecoder(expect=None), pieces) == frame_list


@given(st.lists(st.one_of(st.binary(max_size=30), frames().map(encode)), max_size=8), st.data())
def test_every_byte_is_accounted_for_exactly_once(chunks: list[bytes], data: st.DataObject) -> None:
    wire = b"".join(chunks)
    pieces = data.draw(splits(wire))
    events = drain(StreamDecoder(ZERO_CHECK, expect=None), pieces, eof=True)
    assert all(isinstance(e, (Frame, ProtocolError)) for e in events)
    assert _accounted(events) == wire


@given(st.binary(max_size=400), st.data())
def test_arbitrary_bytes_split_or_whole_give_the_same_events(wire: bytes, data: st.DataObject) -> None:
    whole = drain(StreamDecoder(expect=None), [wire], eof=True)
    pieces = drain(StreamDecoder(expect=None), data.draw(splits(wire)), eof=True)
    byte_by_byte = drain(StreamDecoder(expect=None), [wire[i : i + 1] for i in range(len(wire))], eof=True)
    assert _accounted(whole) == _accounted(pieces) == _accounted(byte_by_byte) == wire
    assert [type(e) for e in whole if not isinstance(e, StartWordError)] == [
        type(e) for e in byte_by_byte if not isinstance(e, StartWordError)
    ]

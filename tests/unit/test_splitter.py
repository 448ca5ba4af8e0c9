"""The one lossless splitter (conformance/protocol/splitter.py): every byte accounted for, frames where the
framing rule says, and peek_header() reading what the codec encodes."""

from __future__ import annotations

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from conformance.protocol import (
    DEFAULT_PROFILE,
    MAX_FRAME_LEN,
    Action,
    ErrorCode,
    Header,
    PieceKind,
    Splitter,
    StreamDecoder,
    answer,
    codec_for,
    encode,
    encode_raw,
    frame_span,
    header_field_bytes,
    peek_action,
    peek_header,
    peek_transfer_type,
    pose_blocks,
    request,
    split_bytes,
    tolerance_blocks,
)
from conformance.protocol.splitter import NEED_MORE, NOT_A_FRAME

POSE = encode(request(Action.POSE, pose_blocks([(1.0, 2.0, 3.0, 4.0, 5.0, 6.0)])))
TOLERANCE = encode(request(Action.TOLERANCE, tolerance_blocks([0.5, 0.25])))
CYCLE_ON = encode(request(Action.CYCLE_ON))
ERROR = encode(answer(Action.POSE, ErrorCode.POSE_ERROR))
FRAMES = (POSE, TOLERANCE, CYCLE_ON, ERROR)


def _split_in_chunks(data: bytes, cuts: list[int], byte_order: str = "big") -> list:
    splitter, pieces, at = Splitter(byte_order), [], 0
    for n in cuts:
        pieces += splitter.feed(data[at : at + n])
        at += n
    pieces += splitter.feed(data[at:])
    return pieces + splitter.flush()


@settings(max_examples=300, deadline=None)
@given(st.binary(max_size=400), st.lists(st.integers(0, 40), max_size=20))
def test_split_then_join_gives_random_bytes_back(data: bytes, cuts: list[int]) -> None:
    pieces = _split_in_chunks(data, cuts)
    assert b"".join(p.raw for p in pieces) == data
    assert all(p.raw for p in pieces)
    offsets = [p.offset for p in pieces]
    assert offsets == [sum(len(p.raw) for p in pieces[:i]) for i in range(len(pieces))]
    assert all(p.kind is not PieceKind.TAIL for p in pieces[:-1])  # a tail only at the end


_chunk = st.one_of(st.sampled_from(FRAMES), st.binary(min_size=1, max_size=30),
                   st.sampled_from([b"\xfe", b"\xfe\xfe", b"\xfe\xfe\x00\x02", b"\xfe\xfe\x00\x01\x01\x23\x01\xff\xff\xff"]))


@settings(max_examples=300, deadline=None)
@given(st.lists(_chunk, max_size=12), st.lists(st.integers(0, 60), max_size=20))
def test_split_then_join_gives_frames_and_garbage_back(chunks: list[bytes], cuts: list[int]) -> None:
    data = b"".join(chunks)
    pieces = _split_in_chunks(data, cuts)
    assert b"".join(p.raw for p in pieces) == data
    for p in pieces:
        if p.kind is PieceKind.FRAME:
            assert frame_span(p.raw) == len(p.raw) and p.action == p.raw[5]
        else:
            assert p.action is None


@settings(max_examples=200, deadline=None)
@given(st.lists(st.sampled_from(FRAMES), min_size=1, max_size=10), st.lists(st.integers(1, 50), max_size=20))
def test_valid_frames_come_out_whole_however_they_are_cut(frames: list[bytes], cuts: list[int]) -> None:
    pieces = _split_in_chunks(b"".join(frames), cuts)
    assert [p.raw for p in pieces] == frames and all(p.is_frame for p in pieces)


def test_garbage_before_between_and_a_tail_after() -> None:
    data = b"xyz" + POSE + b"\xfe\xfe\x00\x02junk" + CYCLE_ON + POSE[:20]
    pieces = split_bytes(data)
    assert [(p.kind, p.raw) for p in pieces] == [
        (PieceKind.GARBAGE, b"xyz"), (PieceKind.FRAME, POSE), (PieceKind.GARBAGE, b"\xfe\xfe\x00\x02junk"),
        (PieceKind.FRAME, CYCLE_ON), (PieceKind.TAIL, POSE[:20])]
    assert pieces[1].action == Action.POSE and pieces[3].offset == 3 + len(POSE) + 8


def test_the_splitter_waits_for_a_frame_and_holds_no_more() -> None:
    splitter = Splitter()
    assert splitter.feed(POSE[:-1]) == [] and splitter.pending == len(POSE) - 1
    (piece,) = splitter.feed(POSE[-1:])
    assert piece.raw == POSE and splitter.pending == 0 and splitter.offset == len(POSE)
    assert splitter.flush() == []


def test_a_header_announcing_more_than_the_largest_frame_is_garbage() -> None:
    huge = encode_raw(Header(block_count=255, block_length=26))
    assert frame_span(huge) == NOT_A_FRAME
    pieces = split_bytes(huge + CYCLE_ON)
    assert [p.kind for p in pieces] == [PieceKind.GARBAGE, PieceKind.FRAME] and pieces[1].raw == CYCLE_ON


def test_the_splitter_frames_as_the_stream_decoder_does() -> None:
    """The decoder (which judges) and the splitter (which only cuts) take the same frames."""
    data = b"\x00\x01" + POSE + b"\xfe\xfe\x00\x02" + bytes(10) + TOLERANCE + ERROR
    decoder = StreamDecoder(expect=None)
    events = decoder.feed(data) + decoder.feed(b"")
    frames = [p.raw for p in split_bytes(data) if p.is_frame]
    assert [codec_for().encode(e) for e in events if not isinstance(e, Exception)] == frames


@settings(max_examples=300, deadline=None)
@given(st.lists(_chunk, max_size=12))
def test_the_splitter_cuts_where_the_stream_decoder_cuts(chunks: list[bytes]) -> None:
    """The frames the splitter cuts are the frames the decoder takes whole (judged or not); the rest (garbage
    runs, a tail) the decoder reports as errors, cut there or not."""
    data = b"".join(chunks)
    decoder, spans = StreamDecoder(expect=None), []
    decoder.receive_data(data) if data else None
    decoder.receive_data(b"")
    while True:
        start = decoder.offset
        if not isinstance(decoder.next_event(), (Exception, type(request(Action.NONE)))):
            break
        spans.append((start, decoder.offset - start))
    taken = [(at, n) for at, n in spans if frame_span(data[at : at + n]) == n]
    assert [(p.offset, len(p.raw)) for p in split_bytes(data) if p.is_frame] == taken


def test_little_endian_headers() -> None:
    little = DEFAULT_PROFILE.replace(byte_order="little")
    data = encode(request(Action.POSE, pose_blocks([(1, 2, 3, 4, 5, 6)])), little)
    assert frame_span(data, 0, "little") == len(data) and frame_span(data) == NOT_A_FRAME
    assert [p.kind for p in split_bytes(data, "little")] == [PieceKind.FRAME]


def test_frame_span_needs_a_whole_header_to_decide() -> None:
    assert frame_span(POSE[:11]) == NEED_MORE and frame_span(b"\xfe") == NEED_MORE
    assert frame_span(b"\xfe\xfe\x00\x02") == NOT_A_FRAME and frame_span(b"ab") == NOT_A_FRAME
    assert frame_span(b"..." + POSE, 3) == len(POSE)


@given(st.sampled_from(list(Action)), st.integers(0, 0xFFFF), st.sampled_from(["big", "little"]))
def test_peek_header_reads_what_the_codec_writes(action: Action, code: int, order: str) -> None:
    profile = DEFAULT_PROFILE.replace(byte_order=order)
    data = encode(answer(action, code, tolerance_blocks([0.5, 1.5, 2.5])), profile)
    head = peek_header(data, 0, order)
    assert head is not None and head.start_ok and head.version_ok and head.trusted and head.is_answer
    assert (head.action, head.error_code, head.block_count, head.block_length) == (action, code, 3, 5)
    assert head.frame_length == len(data) and head.known_action and not head.is_request
    assert peek_action(data) == action and peek_transfer_type(data) == 0x10


def test_peek_on_short_or_wrong_bytes() -> None:
    assert peek_header(POSE[:11]) is None and peek_header(CYCLE_ON, 3) is None and peek_header(CYCLE_ON, -1) is None
    assert peek_action(POSE[:5]) is None and peek_action(POSE[:6]) == Action.POSE
    assert peek_transfer_type(POSE[:4]) is None and peek_transfer_type(POSE[:5]) == 0x01
    head = peek_header(b"\xfe\xff\x00\x02\x01\x99\x00\x00\x00\x00\x00\x00")
    assert head is not None and not head.start_ok and not head.version_ok and not head.known_action
    assert not head.trusted and head.frame_length == 14
    assert header_field_bytes(ERROR, "error_code") == b"\x10\x01" and header_field_bytes(POSE[:9], "block_length") == b"\x00"


@pytest.mark.parametrize("n", [1, 255])
def test_the_largest_legal_frames_are_frames(n: int) -> None:
    data = encode(request(Action.POSE, pose_blocks([(0, 0, 0, 0, 0, 0)] * n)))
    assert frame_span(data) == len(data) <= MAX_FRAME_LEN

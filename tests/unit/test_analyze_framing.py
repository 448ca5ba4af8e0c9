"""One direction's frames (conformance/analyze/framing.py): the same events as the codec's
StreamDecoder for every way the bytes are split, the capture's frame numbers, and
resynchronisation after a gap or a mid-connection start (skipped bytes are not judged)."""

from __future__ import annotations

from hypothesis import given, settings
from hypothesis import strategies as st

from conformance.analyze.framing import FrameReader, plausible_header
from conformance.protocol import (
    DEFAULT_PROFILE,
    Action,
    Frame,
    Header,
    LengthError,
    ProtocolError,
    StreamDecoder,
    TransferType,
    answer,
    encode,
    encode_raw,
    pose_blocks,
    request,
)

R2B = TransferType.ROBOT_TO_BOX
POSE = encode(request(Action.POSE, pose_blocks([(1.0, 2.0, 3.0, 4.0, 5.0, 6.0)])))
NONE = encode(request(Action.NONE))
BAD_INDEX = encode_raw(Header(action=Action.POSE, block_type=1, block_count=1, block_length=25), bytes([1]) + bytes(24))
WRONG_DIR = encode(answer(Action.NONE))
PIECES = [POSE, NONE, BAD_INDEX, WRONG_DIR, b"garbage!", b"\xfe", b"\xfe\xfe\x00\x02" + bytes(10), POSE * 3]


class Out:
    def __init__(self) -> None:
        self.events: list[tuple] = []

    def __call__(self, event, raw, offset, first, last, ts) -> None:
        self.events.append((event, bytes(raw), offset, first, last))


def reference(chunks: list[bytes]) -> list:
    """What the codec's decoder reports for the same chunks."""
    dec = StreamDecoder(DEFAULT_PROFILE, R2B)
    events = []
    for chunk in chunks:
        events += dec.feed(chunk)
    return events + dec.feed(b"")


@settings(max_examples=200)
@given(st.lists(st.sampled_from(PIECES), min_size=1, max_size=8), st.lists(st.integers(1, 60), max_size=20))
def test_same_events_as_the_stream_decoder_for_every_split(pieces, cuts):
    data = b"".join(pieces)
    out = Out()
    reader = FrameReader(DEFAULT_PROFILE, R2B, out)
    pos, chunks = 0, []
    for size in cuts + [len(data)]:
        if data[pos : pos + size]:
            chunks.append(data[pos : pos + size])
        pos += size
        if pos >= len(data):
            break
    for n, chunk in enumerate(chunks, 1):
        reader.feed(chunk, n, float(n))
    reader.close(len(chunks) + 1, 0.0)
    assert [e[0] for e in out.events] == reference(chunks)
    # every event's bytes are where its offset says, and they tile the stream
    assert b"".join(e[1] for e in out.events) == data
    assert [e[2] for e in out.events] == [sum(len(x[1]) for x in out.events[:i]) for i in range(len(out.events))]


def test_frame_numbers_of_a_frame_in_pieces():
    out = Out()
    reader = FrameReader(DEFAULT_PROFILE, R2B, out)
    reader.feed(POSE[:10], 7, 1.0)
    reader.feed(POSE[10:30], 8, 1.1)
    reader.feed(POSE[30:] + NONE, 9, 1.2)
    assert [(type(e[0]), e[3], e[4]) for e in out.events] == [(Frame, 7, 9), (Frame, 9, 9)]


def test_a_frame_cut_by_a_gap_is_not_judged_and_the_next_one_is():
    out = Out()
    reader = FrameReader(DEFAULT_PROFILE, R2B, out)
    reader.feed(POSE[:20], 1, 0.0)
    reader.gap(100)
    reader.feed(POSE[5:] + NONE + POSE, 2, 0.1)  # the rest of some frame, then whole frames
    assert reader.cut == 1 and reader.skipped == len(POSE) - 5
    assert [e[0].action for e in out.events] == [Action.NONE, Action.POSE]
    assert out.events[0][2] == 20 + 100 + len(POSE) - 5  # offsets count the missing bytes


def test_a_mid_connection_start_skips_to_a_plausible_header():
    out = Out()
    reader = FrameReader(DEFAULT_PROFILE, R2B, out)
    reader.mark_midstart()
    stream = POSE[13:] + POSE + NONE
    for i in range(0, len(stream), 3):  # a header split across chunks is still found
        reader.feed(stream[i : i + 3], i, 0.0)
    assert [e[0].action for e in out.events] == [Action.POSE, Action.NONE]
    assert reader.skipped == len(POSE) - 13 and not any(isinstance(e[0], ProtocolError) for e in out.events)


def test_a_stream_that_ends_inside_a_frame_is_an_f5_error_but_a_capture_that_ends_is_not():
    out = Out()
    reader = FrameReader(DEFAULT_PROFILE, R2B, out)
    reader.feed(NONE + POSE[:20], 1, 0.0)
    reader.close(2, 0.0)
    assert isinstance(out.events[-1][0], LengthError) and out.events[-1][0].clause == "F5"
    out2 = Out()
    reader2 = FrameReader(DEFAULT_PROFILE, R2B, out2)
    reader2.feed(NONE + POSE[:20], 1, 0.0)
    reader2.end()
    assert len(out2.events) == 1 and reader2.cut == 1


def test_plausible_header():
    assert plausible_header(b"xx" + POSE) == 2
    assert plausible_header(b"\xfe\xfe\x00\x01\x01\x99" + POSE) == 6  # action 0x99 is unknown
    assert plausible_header(WRONG_DIR, expect=0x01) == -1 and plausible_header(WRONG_DIR, expect=0x10) == 0
    assert plausible_header(b"\xfe\xfe\x01\x00\x01\x23", profile=DEFAULT_PROFILE.replace(byte_order="little")) == 0
    assert plausible_header(b"\xfe\xfe\x01\x00\x01\x23") == -1

"""Frames cut by the capture's snap length (conformance/analyze/snapcut.py, FrameReader.snap): a count of bytes at
a known place, so the cut frame is judged on its header and framing goes on after it; a gap only when the kept
bytes do not tell where the frame ends."""

from __future__ import annotations

from typing import Any

from conformance.analyze.framing import FrameReader
from conformance.analyze.snapcut import SnapCut, span_of_prefix
from conformance.protocol import (
    DEFAULT_PROFILE,
    Action,
    Frame,
    TransferType,
    encode,
    frame_spanner,
    pose_blocks,
    request,
)

POSE = encode(request(Action.POSE, pose_blocks([(800.0, 10.0, 300.0, 180.0, 0.0, 90.0)])))  # 39 bytes
NONE = encode(request(Action.NONE))  # 14 bytes


def reader() -> tuple[FrameReader, list[tuple[Any, ...]]]:
    seen: list[tuple[Any, ...]] = []
    r = FrameReader(DEFAULT_PROFILE, TransferType.ROBOT_TO_BOX, lambda *event: seen.append(event))
    return r, seen


def test_a_frame_cut_after_its_first_10_bytes_is_a_snapcut_and_the_next_frame_is_read() -> None:
    r, seen = reader()
    r.feed(POSE[:10], 1, 1.0)
    assert r.snap(29, 1, 1.0) is True
    r.feed(NONE, 2, 2.0)
    (cut, raw, offset, first, last, ts), (frame, *_rest) = seen
    assert isinstance(cut, SnapCut) and (cut.size, cut.kept, cut.action, cut.error_code) == (39, 10, Action.POSE, None)
    assert (raw, offset, first, last, ts) == (POSE[:10], 0, 1, 1, 1.0)
    assert "cut by the capture's snap length after 10 byte(s)" in cut.message
    assert type(frame) is Frame and frame.action is Action.NONE and seen[1][2] == 39
    assert r.cut == 0 and r.skipped == 0


def test_a_cut_frame_that_runs_into_the_next_packet_ends_there() -> None:
    r, seen = reader()
    r.feed(POSE[:10], 1, 1.0)
    r.snap(10, 1, 1.0)  # packet 1: 20 bytes on the wire, 10 kept
    r.feed(POSE[20:] + NONE, 2, 2.0)  # packet 2 kept whole: the frame's last 19 bytes, then a NONE
    assert [type(e[0]) for e in seen] == [SnapCut, Frame]
    assert seen[0][3:5] == (1, 2)  # from packet 1 to packet 2: its time is packet 2's
    assert seen[1][2] == 39


def test_twelve_bytes_kept_tell_the_error_code() -> None:
    r, seen = reader()
    r.feed(POSE[:12], 1, 1.0)
    r.snap(27, 1, 1.0)
    assert seen[0][0].error_code == 0 and "its blocks and check field" in seen[0][0].message


def test_fewer_than_10_bytes_do_not_tell_the_length_so_they_are_a_gap() -> None:
    r, seen = reader()
    r.feed(POSE[:8], 1, 1.0)
    assert r.snap(31, 1, 1.0) is False
    assert seen == [] and r.cut == 1
    r.feed(b"\x00" * 3 + NONE, 2, 2.0)  # resynchronised at the next plausible header
    assert [type(e[0]) for e in seen] == [Frame]


def test_bytes_not_kept_past_the_frames_end_are_a_gap() -> None:
    r, seen = reader()
    r.feed(POSE[:10], 1, 1.0)
    assert r.snap(29 + len(NONE), 1, 1.0) is False  # a second frame wholly in the part not kept
    assert [type(e[0]) for e in seen] == [SnapCut]


def test_the_span_needs_a_plausible_header() -> None:
    span = frame_spanner("big")
    assert span_of_prefix(POSE[:10], span) == 39 and span_of_prefix(POSE[:9], span) == 0
    assert span_of_prefix(b"\x00" * 10, span) == 0

"""The fewest frames that still show a defect: split what a case sent into frames, then drop what is not needed.

:func:`split_frames` cuts bytes at the frame lengths their headers announce (bytes that do not
start with the start word, or a frame cut short, stay one piece: they are sent as they were).
:func:`shrink` drops frames, earliest first, as long as the defect still shows without them
(each try is one live exchange, so the caller's predicate bounds the time).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

from ..protocol import HEADER_LEN, Codec, parse_header
from ..protocol.constants import START_WORD


def split_frames(data: bytes, codec: Codec) -> list[bytes]:
    """``data`` cut into the frames its headers announce; anything else stays one piece."""
    out: list[bytes] = []
    at = 0
    while at < len(data):
        if len(data) - at >= HEADER_LEN and parse_header(data[at:at + HEADER_LEN]).start_word == START_WORD:
            end = at + codec.frame_length(data, at)
            if end <= len(data):
                out.append(data[at:end])
                at = end
                continue
        out.append(data[at:])
        break
    return out


def shrink(frames: Sequence[bytes], shows: Callable[[Sequence[bytes]], bool | None], max_tries: int = 12) -> list[bytes]:
    """The fewest of ``frames`` (in order, the last always kept) for which ``shows`` is still True.
    ``shows`` returning None (out of time) stops the search with what is known to show it."""
    kept = list(frames)
    tries = 0
    i = 0
    while i < len(kept) - 1 and tries < max_tries:
        candidate = kept[:i] + kept[i + 1:]
        tries += 1
        verdict = shows(candidate)
        if verdict is None:
            break
        if verdict:
            kept = candidate
        else:
            i += 1
    return kept

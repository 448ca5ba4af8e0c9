"""The one lossless splitter: bytes in any split in, frames, garbage runs and a tail out (sans-I/O).

Every reader of raw iSight bytes outside this package (analyze's fast path, the monitor's
fault injector, the fuzzer's oracle and coverage, the catalogue) reads a header through
:func:`peek_header` (or :func:`peek_action` / :func:`peek_transfer_type` for a header
that may be cut short) and cuts a stream with :class:`Splitter`; no header offset lives
anywhere else.

Framing rule (the one :class:`~.stream.StreamDecoder` applies): a header is trusted when
it starts with the start word (F1), carries version 1 in the byte order (F2) and
announces at most the largest legal frame (F5). A trusted header's frame is taken whole
(header + N × L + check), legal or not: judging it is the codec's work. Any other bytes
form a garbage run up to the next FE FE (past the start word of a header that is not
trusted, as the decoder resynchronises). Joining the pieces gives the input back
exactly; :meth:`Splitter.flush` returns the incomplete tail. The splitter holds at most
one frame's bytes (:data:`~.constants.MAX_FRAME_LEN`) plus what one ``feed`` brought.
"""

from __future__ import annotations

import enum
import struct
from collections.abc import Callable
from dataclasses import dataclass
from functools import lru_cache
from typing import NamedTuple

from .constants import (
    CHECK_LEN,
    HEADER_FIELDS,
    HEADER_LEN,
    MAX_FRAME_LEN,
    START_BYTES,
    START_WORD,
    VERSION,
    Action,
    TransferType,
)

__all__ = [
    "NEED_MORE", "NOT_A_FRAME", "HeaderPeek", "Piece", "PieceKind", "Splitter", "find_plausible_header", "frame_span",
    "header_field_bytes",
    "frame_spanner", "peek_action",
    "peek_header", "peek_transfer_type", "split_bytes",
]

_ACTION_AT, _TRANSFER_AT = HEADER_FIELDS["action"][0], HEADER_FIELDS["transfer_type"][0]
_ACTIONS = frozenset(int(a) for a in Action)
_TRANSFERS = frozenset(int(t) for t in TransferType)
#: frame_span(): the bytes before here do not hold enough to decide
NEED_MORE = 0
#: frame_span(): no trusted header starts here
NOT_A_FRAME = -1


@dataclass(frozen=True, slots=True)
class HeaderPeek:
    """The twelve header bytes read in one byte order, legal or not, with what framing needs."""

    start_word: int
    version: int
    transfer_type: int
    action: int
    block_type: int
    block_count: int
    block_length: int
    error_code: int

    @property
    def start_ok(self) -> bool:
        """F1: the frame starts with FE FE."""
        return self.start_word == START_WORD

    @property
    def version_ok(self) -> bool:
        """F2: version 1 in this byte order."""
        return self.version == VERSION

    @property
    def body_length(self) -> int:
        """N × L: the block bytes this header announces."""
        return self.block_count * self.block_length

    @property
    def frame_length(self) -> int:
        """The whole frame this header announces: header + N × L + check."""
        return HEADER_LEN + self.block_count * self.block_length + CHECK_LEN

    @property
    def trusted(self) -> bool:
        """The framing rule: start word, version 1 and at most the largest legal frame."""
        return self.start_ok and self.version_ok and self.frame_length <= MAX_FRAME_LEN

    @property
    def is_answer(self) -> bool:
        """F3: the box-to-robot transfer type."""
        return self.transfer_type == TransferType.BOX_TO_ROBOT

    @property
    def is_request(self) -> bool:
        """F3: the robot-to-box transfer type."""
        return self.transfer_type == TransferType.ROBOT_TO_BOX

    @property
    def known_action(self) -> bool:
        """A5: the action byte names an action."""
        return self.action in _ACTIONS


class _Layout:
    """The header's structs in one byte order."""

    def __init__(self, byte_order: str) -> None:
        e = ">" if byte_order == "big" else "<"
        self.header = struct.Struct(e + "HHBBBBHH").unpack_from
        self.u16 = struct.Struct(e + "H").unpack_from
        self.start = struct.pack(e + "HH", START_WORD, VERSION)

    def span(self, data: bytes | bytearray, at: int = 0) -> int:
        """See :func:`frame_span`."""
        if len(data) - at < HEADER_LEN:
            return NEED_MORE if self.start.startswith(bytes(data[at : at + 4])) else NOT_A_FRAME
        if data[at : at + 4] != self.start:
            return NOT_A_FRAME
        total: int = HEADER_LEN + data[at + 7] * self.u16(data, at + 8)[0] + CHECK_LEN
        return total if total <= MAX_FRAME_LEN else NOT_A_FRAME


@lru_cache(maxsize=4)
def _layout(byte_order: str) -> _Layout:
    if byte_order not in ("big", "little"):
        raise ValueError(f"byte order {byte_order!r}: big or little")
    return _Layout(byte_order)


def peek_header(data: bytes | bytearray | memoryview, at: int = 0, byte_order: str = "big") -> HeaderPeek | None:
    """The header at ``at`` read in ``byte_order`` (the profile's), None if fewer than 12 bytes are there."""
    if len(data) - at < HEADER_LEN or at < 0:
        return None
    return HeaderPeek(*_layout(byte_order).header(data, at))


def header_field_bytes(data: bytes | bytearray, name: str, at: int = 0) -> bytes:
    """One header field's bytes as on the wire (:data:`~.constants.HEADER_FIELDS` names it), as many of
    them as ``data`` holds (b"" past its end)."""
    offset, width = HEADER_FIELDS[name]
    return bytes(data[at + offset : at + offset + width])


def peek_action(data: bytes | bytearray | memoryview, at: int = 0) -> int | None:
    """The action byte of a header at ``at`` that may be cut short; None if the bytes end before it."""
    return data[at + _ACTION_AT] if 0 <= at and len(data) > at + _ACTION_AT else None


def peek_transfer_type(data: bytes | bytearray | memoryview, at: int = 0) -> int | None:
    """The transfer-type byte (F3) of a header at ``at`` that may be cut short; None if the bytes end before it."""
    return data[at + _TRANSFER_AT] if 0 <= at and len(data) > at + _TRANSFER_AT else None


def frame_span(data: bytes | bytearray, at: int = 0, byte_order: str = "big") -> int:
    """The length of the frame a trusted header at ``at`` announces (it may run past the bytes held),
    :data:`NEED_MORE` (0) if the bytes end before a trusted header could be told, :data:`NOT_A_FRAME` (-1)
    if no trusted header starts there."""
    return _layout(byte_order).span(data, at)


def whole_frames(data: bytes | bytearray, byte_order: str = "big") -> int:
    """How many whole frames ``data`` starts with (a write of several requests, R4), up to the first that is not."""
    at = count = 0
    while at < len(data):
        span = frame_span(data, at, byte_order)
        if span <= 0 or at + span > len(data):
            break
        at, count = at + span, count + 1
    return count


def frame_spanner(byte_order: str = "big") -> Callable[[bytes | bytearray, int], int]:
    """:func:`frame_span` bound to one byte order, for a hot loop."""
    return _layout(byte_order).span


def find_plausible_header(data: bytes | bytearray, start: int = 0, expect: int | None = None,
                          byte_order: str = "big") -> int:
    """Index of the first plausible header at or after ``start`` (where to resynchronise when the bytes
    did not start at a frame): start word and version 1 in ``byte_order``, transfer type ``expect`` (or
    either), a known action. -1 if none."""
    head = _layout(byte_order).start
    pos = data.find(START_BYTES, start)
    while 0 <= pos <= len(data) - (_ACTION_AT + 1):
        if data[pos : pos + 4] == head and (data[pos + _TRANSFER_AT] == expect if expect is not None
                                            else data[pos + _TRANSFER_AT] in _TRANSFERS) \
                and data[pos + _ACTION_AT] in _ACTIONS:
            return pos
        pos = data.find(START_BYTES, pos + 1)
    return -1


class PieceKind(enum.Enum):
    FRAME = "frame"  # a trusted header's whole frame (legal or not)
    GARBAGE = "garbage"  # bytes up to the next FE FE that start no trusted header
    TAIL = "tail"  # what was left when the stream ended (an incomplete frame or a lone FE)


class Piece(NamedTuple):
    """One piece of the stream: ``offset`` counts from the splitter's first byte."""

    raw: bytes
    kind: PieceKind
    offset: int
    action: int | None  # a frame's action byte; None for garbage and a tail

    @property
    def is_frame(self) -> bool:
        return self.kind is PieceKind.FRAME


_FRAME, _GARBAGE, _TAIL = PieceKind.FRAME, PieceKind.GARBAGE, PieceKind.TAIL


class Splitter:
    """Cut one direction's bytes into :class:`Piece` s, keeping every byte."""

    def __init__(self, byte_order: str = "big") -> None:
        layout = _layout(byte_order)
        self._start = layout.start
        self._u16 = layout.u16
        self._buf = bytearray()
        self._base = 0  # stream offset of _buf[0]

    @property
    def pending(self) -> int:
        """Bytes held, waiting for the rest of a frame."""
        return len(self._buf)

    @property
    def offset(self) -> int:
        """Stream offset of the first byte held (of the next piece)."""
        return self._base

    def feed(self, data: bytes) -> list[Piece]:
        """The whole pieces the bytes so far complete."""
        buf = self._buf
        buf += data
        out: list[Piece] = []
        start, u16, base, new = self._start, self._u16, self._base, tuple.__new__  # Piece without its slow __new__
        pos, size = 0, len(buf)
        while pos < size:
            avail = size - pos
            if avail >= HEADER_LEN:
                if buf[pos : pos + 4] == start:
                    total = HEADER_LEN + buf[pos + 7] * u16(buf, pos + 8)[0] + CHECK_LEN
                    if total <= MAX_FRAME_LEN:
                        if avail < total:
                            break
                        out.append(new(Piece, (bytes(buf[pos : pos + total]), _FRAME, base + pos, buf[pos + _ACTION_AT])))
                        pos += total
                        continue
            elif start.startswith(buf[pos : pos + 4]):
                break  # a header may still come
            # past a start word whose header is not trusted, as the stream decoder resynchronises (R6)
            nxt = buf.find(START_BYTES, pos + (2 if buf[pos] == 0xFE and buf[pos + 1 : pos + 2] == b"\xfe" else 1))
            if nxt < 0:
                nxt = size - 1 if buf[-1] == 0xFE else size  # a trailing FE may start a frame
                if nxt <= pos:
                    break
            out.append(Piece(bytes(buf[pos:nxt]), _GARBAGE, base + pos, None))
            pos = nxt
        if pos:
            del buf[:pos]
            self._base = base + pos
        return out

    def flush(self) -> list[Piece]:
        """The stream ended: what is held comes out as one tail piece (none if nothing is held)."""
        if not self._buf:
            return []
        piece = Piece(bytes(self._buf), _TAIL, self._base, None)
        self._base += len(self._buf)
        self._buf.clear()
        return [piece]


def split_bytes(data: bytes, byte_order: str = "big") -> list[Piece]:
    """All of ``data`` as pieces: frames, garbage runs and (last, if any) the incomplete tail."""
    splitter = Splitter(byte_order)
    return splitter.feed(data) + splitter.flush()

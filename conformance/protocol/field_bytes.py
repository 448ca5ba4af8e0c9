"""Every byte of every multi-byte field (F4): where each lies, and the one-byte changes a case sends.

The table is derived from the frame layout, not listed by hand: every header field of
:data:`~.constants.HEADER_FIELDS` wider than one byte (start word, version, block length,
error code), then the check field (the frame's last :data:`~.constants.CHECK_LEN` bytes).
A :class:`ByteChange` alters one byte of one field and leaves every other byte of the frame
as it was, so a receiver that reads only some bytes of a field (the low byte of the block
length: L = 0x0119 taken as 25) takes the changed frame for the valid one.

A header field's bytes are named by significance (byte 0 the most significant), so a change
gives the same field value under either byte order (F4, ``--byte-order``); the check field's
bytes are named by their place on the wire (its byte order is the CRC's, ``--crc-byte-order``).
Sans-I/O.
"""

from __future__ import annotations

from dataclasses import dataclass

from .constants import CHECK_LEN, HEADER_FIELDS, HEADER_LEN, MAX_FRAME_LEN

#: The clause each multi-byte field's value stands under (the check field: over UDP, F7).
FIELD_CLAUSE = {"start_word": "F1", "version": "F2", "block_length": "F5", "error_code": "A3", "check": "F7"}
#: The changes made to each byte: XOR masks (the lowest bit, every bit), so the byte always differs from the valid one.
MASKS = (0x01, 0xFF)


@dataclass(frozen=True)
class FieldSpan:
    """One multi-byte field: its name, offset (negative: from the frame's end) and width in bytes."""

    name: str
    offset: int
    width: int

    @property
    def clause(self) -> str:
        return FIELD_CLAUSE[self.name]

    @property
    def in_header(self) -> bool:
        return 0 <= self.offset < HEADER_LEN

    def start(self, frame_len: int) -> int:
        """The field's first byte in a frame of ``frame_len`` bytes."""
        return self.offset if self.offset >= 0 else frame_len + self.offset


#: Every multi-byte field, in wire order: the header's, then the check field.
MULTI_BYTE_FIELDS: tuple[FieldSpan, ...] = (
    *(FieldSpan(name, offset, width) for name, (offset, width) in HEADER_FIELDS.items() if width > 1),
    FieldSpan("check", -CHECK_LEN, CHECK_LEN),
)
FIELDS_BY_NAME = {f.name: f for f in MULTI_BYTE_FIELDS}


@dataclass(frozen=True)
class ByteChange:
    """Byte ``byte`` of field ``field`` XORed with ``mask``; every other byte of the frame kept."""

    field: str
    byte: int  # header fields: significance (0 = most significant); the check field: place on the wire
    mask: int

    @property
    def span(self) -> FieldSpan:
        return FIELDS_BY_NAME[self.field]

    def position(self, frame_len: int, byte_order: str = "big") -> int:
        """Where the changed byte lies in a frame of ``frame_len`` bytes whose header is in ``byte_order``."""
        span = self.span
        on_wire = self.byte if not span.in_header or byte_order == "big" else span.width - 1 - self.byte
        return span.start(frame_len) + on_wire

    def apply(self, frame: bytes, byte_order: str = "big") -> bytes:
        """``frame`` with the one byte changed."""
        out = bytearray(frame)
        out[self.position(len(frame), byte_order)] ^= self.mask
        return bytes(out)

    def value(self, valid: int) -> int:
        """The field's value after the change, from its valid value (header fields)."""
        return valid ^ (self.mask << 8 * (self.span.width - 1 - self.byte))

    def describe(self, valid: int | None = None) -> str:
        """E.g. ``block_length 0x0019 -> 0x0119 (byte 0 of 2, XOR 01)``; ``valid`` None: the byte only."""
        where = f"byte {self.byte} of {self.span.width}, XOR {self.mask:02x}"
        if valid is None:
            return f"{self.field} ({where})"
        digits = 2 * self.span.width
        return f"{self.field} 0x{valid:0{digits}X} -> 0x{self.value(valid):0{digits}X} ({where})"


def byte_changes(*names: str) -> tuple[ByteChange, ...]:
    """Every change of the named fields (every multi-byte field when none is named): each byte, each mask."""
    spans = [FIELDS_BY_NAME[n] for n in names] if names else list(MULTI_BYTE_FIELDS)
    return tuple(ByteChange(s.name, b, m) for s in spans for b in range(s.width) for m in MASKS)


def completed(frame: bytes, announced: int) -> bytes:
    """``frame`` (TCP, check 00 00) padded with zero bytes to the ``announced`` length its changed header gives,
    when that is longer and a legal header could announce it (at most :data:`~.constants.MAX_FRAME_LEN`): a
    receiver that reads the whole field then waits for no byte that never comes, and one that reads part of it
    still takes the first ``len(frame)`` bytes for a frame."""
    if len(frame) < announced <= MAX_FRAME_LEN:
        return frame + bytes(announced - len(frame))
    return frame

"""Typed parse errors. Each names the PROTOCOL.md clause it breaks and the offset.

The stream decoder returns these as events (it never raises them); the datagram
decoder and :func:`~conformance.protocol.api.parse_frame` raise them. Either way a
verdict can quote ``clause``, ``offset``, ``raw`` and the parsed ``header``.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from .frames import Header


class ProtocolError(Exception):
    """Base class: bytes that are not a conforming frame."""

    clause = "F"
    #: True when the broken rule is a SHOULD (lenient profiles accept it).
    should = False

    def __init__(
        self,
        message: str,
        *,
        offset: int = 0,
        raw: bytes = b"",
        header: Header | None = None,
        clause: str | None = None,
    ) -> None:
        super().__init__(message)
        self.message = message
        self.offset = offset
        self.raw = bytes(raw)
        self.header = header
        if clause is not None:
            self.clause = clause

    def __str__(self) -> str:
        return f"[{self.clause}] {self.message} (at offset {self.offset})"

    def __repr__(self) -> str:
        return f"{type(self).__name__}({self.clause!r}, {self.message!r}, offset={self.offset})"

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, ProtocolError):
            return NotImplemented
        return (type(self), self.clause, self.message, self.offset, self.raw) == (
            type(other),
            other.clause,
            other.message,
            other.offset,
            other.raw,
        )

    def __hash__(self) -> int:
        return hash((type(self), self.clause, self.offset, self.raw))


class StartWordError(ProtocolError):
    """F1: bytes that do not begin with FE FE (garbage skipped while resynchronising)."""

    clause = "F1"


class VersionError(ProtocolError):
    clause = "F2"


class DirectionError(ProtocolError):
    """F3: transfer type not 01 (robot→box) / 10 (box→robot) as expected."""

    clause = "F3"


class LengthError(ProtocolError):
    """F5: not exactly 12 + N*L + 2 bytes (truncated, trailing, or oversized)."""

    clause = "F5"


class CheckError(ProtocolError):
    """F6 (TCP check not 00 00) or F7 (UDP CRC mismatch)."""

    clause = "F7"


class UnknownActionError(ProtocolError):
    clause = "A5"


class ShapeError(ProtocolError):
    """B1/B2/B5/E1/E2/E3/A2: block type, count or length wrong for the action."""

    clause = "B5"


class AnswerError(ProtocolError):
    """A4/E3: a well-formed answer whose content the protocol forbids."""

    clause = "A4"


class BlockIndexError(ProtocolError):
    clause = "B3"


class FloatError(ProtocolError):
    """B4: NaN or infinity in a pose or tolerance (a SHOULD)."""

    clause = "B4"
    should = True

"""The TCP stream decoder: bytes in any split in, frames and typed errors out.

Like h11, it does no I/O: call :meth:`StreamDecoder.receive_data` with what the
socket gave (``b""`` for end of stream), then :meth:`StreamDecoder.next_event` until
it returns :data:`NEED_DATA` or :data:`CLOSED`. An event is a
:class:`~.frames.Frame` or a :class:`~.errors.ProtocolError` *instance* (returned,
never raised); error offsets count from the start of the stream.

Framing trusts a header only when its start word (F1) and version (F2) are right
and it announces at most the largest legal frame (F5). Such a header's frame is
taken whole, so one malformed frame is one error event and the next frame stays in
step. Any other bytes are skipped up to the next FE FE (R6, resynchronisation),
reported as one error naming the clause. The decoder never waits for more than
:data:`~.constants.MAX_FRAME_LEN` bytes of one frame.
"""

from __future__ import annotations

import struct
from collections.abc import Iterator

from .codec import codec_for
from .constants import CHECK_LEN, HEADER_LEN, MAX_BLOCK_COUNT, MAX_BLOCK_LEN, MAX_FRAME_LEN, TransferType, Transport
from .errors import LengthError, ProtocolError, StartWordError, VersionError
from .frames import Frame
from .profile import DEFAULT_PROFILE, Profile


class _Sentinel:
    def __init__(self, name: str) -> None:
        self._name = name

    def __repr__(self) -> str:
        return self._name


#: More bytes are needed before the next event.
NEED_DATA = _Sentinel("NEED_DATA")
#: End of stream was received and every byte has been reported.
CLOSED = _Sentinel("CLOSED")

Event = Frame | ProtocolError
_MAX_BODY = MAX_BLOCK_COUNT * MAX_BLOCK_LEN
_START = b"\xfe\xfe"
_COMPACT_AT = 1 << 16


class StreamDecoder:
    """Decode a TCP byte stream in one direction.

    ``expect`` is the transfer type this side receives (F3): robot→box frames at
    the box, box→robot frames at the robot; None accepts both.
    """

    def __init__(
        self, profile: Profile = DEFAULT_PROFILE, expect: TransferType | None = TransferType.ROBOT_TO_BOX
    ) -> None:
        self.profile = profile
        self.expect = expect
        self._codec = codec_for(profile)
        self._parse = self._codec.parse
        self._len = struct.Struct(">H" if profile.byte_order == "big" else "<H").unpack_from
        self._version = struct.Struct(">H" if profile.byte_order == "big" else "<H").unpack_from
        self._buf = bytearray()
        self._pos = 0  # next unread byte in _buf
        self._base = 0  # stream offset of _buf[0]
        self._eof = False

    # -- input -----------------------------------------------------------------------
    def receive_data(self, data: bytes) -> None:
        """Add bytes from the stream; ``b""`` means the peer closed its side."""
        if not data:
            self._eof = True
            return
        if self._eof:
            raise RuntimeError("receive_data after end of stream")
        if self._pos and (self._pos == len(self._buf) or self._pos >= _COMPACT_AT):
            del self._buf[: self._pos]
            self._base += self._pos
            self._pos = 0
        self._buf += data

    @property
    def buffered(self) -> int:
        """Bytes received and not yet reported in an event."""
        return len(self._buf) - self._pos

    @property
    def offset(self) -> int:
        """Stream offset of the next unread byte."""
        return self._base + self._pos

    @property
    def eof(self) -> bool:
        return self._eof

    # -- output ------------------------------------------------------------------------
    def next_event(self) -> Event | _Sentinel:
        buf, pos = self._buf, self._pos
        avail = len(buf) - pos
        if avail >= HEADER_LEN and buf[pos] == 0xFE and buf[pos + 1] == 0xFE:
            if self._version(buf, pos + 2)[0] != 1:
                version = self._version(buf, pos + 2)[0]
                return self._skip(VersionError, f"version 0x{version:04X}, expected 0x0001", 2)
            body = buf[pos + 7] * self._len(buf, pos + 8)[0]
            if body > _MAX_BODY:
                return self._oversized(body)
            total = HEADER_LEN + body + CHECK_LEN
            if avail < total:
                return self._truncated() if self._eof else NEED_DATA
            data = bytes(buf[pos : pos + total])
            self._pos = pos + total
            try:
                return self._parse(data, Transport.TCP, self.expect)
            except ProtocolError as exc:
                exc.offset += self._base + pos
                return exc
        if avail >= 2 and (buf[pos] != 0xFE or buf[pos + 1] != 0xFE):
            got = bytes(buf[pos : pos + 2]).hex(" ")
            return self._skip(StartWordError, f"{got} where a start word fe fe was expected", 0)
        if avail == 1 and buf[pos] != 0xFE:
            return self._skip(StartWordError, f"{buf[pos]:02x} where a start word fe fe was expected", 0)
        if not avail:
            return CLOSED if self._eof else NEED_DATA
        return self._truncated() if self._eof else NEED_DATA

    def _oversized(self, body: int) -> ProtocolError:
        """A header announcing more than the largest legal frame: name the header field
        that makes it illegal (e.g. B1 for L=6400) if any, else F5; then resynchronise."""
        pos = self._pos
        try:
            self._codec.check_header(bytes(self._buf[pos : pos + HEADER_LEN]), self.expect)
        except ProtocolError as exc:
            return self._skip(type(exc), exc.message, 2, exc.clause)
        message = f"header announces N*L = {body} block bytes, more than the largest legal frame ({MAX_FRAME_LEN} bytes)"
        return self._skip(LengthError, message, 2)

    def _skip(
        self, cls: type[ProtocolError], message: str, search_from: int, clause: str | None = None
    ) -> ProtocolError:
        """Report and drop bytes up to the next FE FE (or all but a trailing FE)."""
        buf, pos = self._buf, self._pos
        nxt = buf.find(_START, pos + max(1, search_from))
        if nxt < 0:
            nxt = len(buf) - (1 if buf[-1] == 0xFE and len(buf) - pos > max(1, search_from) else 0)
            if self._eof:
                nxt = len(buf)
        raw = bytes(buf[pos:nxt])
        self._pos = nxt
        header = self._codec.parse_header(raw) if len(raw) >= HEADER_LEN else None
        return cls(
            f"{message}; skipped {len(raw)} bytes to resynchronise",
            offset=self._base + pos, raw=raw, header=header, clause=clause,
        )

    def _truncated(self) -> ProtocolError:
        buf, pos = self._buf, self._pos
        raw = bytes(buf[pos:])
        self._pos = len(buf)
        header = self._codec.parse_header(raw) if len(raw) >= HEADER_LEN else None
        return LengthError(
            f"stream ended inside a frame after {len(raw)} bytes", offset=self._base + pos, raw=raw, header=header
        )

    def events(self) -> Iterator[Event]:
        """Every event available now."""
        while True:
            event = self.next_event()
            if not isinstance(event, (Frame, ProtocolError)):  # NEED_DATA or CLOSED
                return
            yield event

    def feed(self, data: bytes) -> list[Event]:
        """``receive_data(data)`` then every event available now."""
        self.receive_data(data)
        return list(self.events())

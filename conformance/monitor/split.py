"""Cut one direction's bytes into frames, keeping every byte (sans-I/O).

The fault injector needs to know where each of the box's answers starts and ends and
which action it carries; the reaction log needs the robot's requests. :class:`Splitter`
trusts a header with the start word that announces at most the largest legal frame
(the codec's own framing rule); any other bytes come out as they are, up to the next
start word, with no action. Concatenating the pieces gives the input back exactly.
It holds at most one frame's bytes (:data:`~conformance.protocol.MAX_FRAME_LEN`).
"""

from __future__ import annotations

from ..protocol import HEADER_LEN, MAX_FRAME_LEN
from ..protocol.constants import START_BYTES

__all__ = ["Splitter"]

_START = START_BYTES


class Splitter:
    def __init__(self, big_endian: bool = True) -> None:
        self.big = big_endian
        self.buf = bytearray()

    @property
    def pending(self) -> int:
        return len(self.buf)

    def feed(self, data: bytes) -> list[tuple[bytes, int | None]]:
        """The whole pieces ``data`` completes: (bytes, action) for a frame, (bytes, None) for other bytes."""
        buf = self.buf
        buf += data
        out: list[tuple[bytes, int | None]] = []
        pos, size = 0, len(buf)
        while pos < size:
            if buf[pos] == 0xFE and (size - pos < 2 or buf[pos + 1] == 0xFE):
                if size - pos < HEADER_LEN:
                    break
                length = (buf[pos + 8] << 8 | buf[pos + 9]) if self.big else (buf[pos + 9] << 8 | buf[pos + 8])
                total = HEADER_LEN + buf[pos + 7] * length + 2
                if total <= MAX_FRAME_LEN:
                    if size - pos < total:
                        break
                    out.append((bytes(buf[pos : pos + total]), buf[pos + 5]))
                    pos += total
                    continue
            nxt = buf.find(_START, pos + 1)
            if nxt < 0:
                nxt = size - 1 if buf[-1] == 0xFE else size
                if nxt <= pos:
                    break
            out.append((bytes(buf[pos:nxt]), None))
            pos = nxt
        del buf[:pos]
        return out

    def flush(self) -> bytes:
        """What is left (the stream ended inside a frame)."""
        rest = bytes(self.buf)
        self.buf.clear()
        return rest

"""Cut one direction's bytes into frames, keeping every byte (sans-I/O).

The fault injector needs to know where each of the box's answers starts and ends and
which action it carries; the reaction log needs the robot's requests. This is the
protocol's one lossless splitter (:class:`conformance.protocol.Splitter`, the codec's
framing rule) seen as (bytes, action) pairs: a frame carries its action, any other bytes
come out as they are with no action. Concatenating the pieces gives the input back
exactly. It holds at most one frame's bytes (:data:`~conformance.protocol.MAX_FRAME_LEN`).
"""

from __future__ import annotations

from ..protocol import Splitter as _ProtocolSplitter

__all__ = ["Splitter"]


class Splitter:
    def __init__(self, big_endian: bool = True) -> None:
        self.big = big_endian
        self._split = _ProtocolSplitter("big" if big_endian else "little")

    @property
    def pending(self) -> int:
        return self._split.pending

    def feed(self, data: bytes) -> list[tuple[bytes, int | None]]:
        """The whole pieces ``data`` completes: (bytes, action) for a frame, (bytes, None) for other bytes."""
        return [(p.raw, p.action) for p in self._split.feed(data)]

    def flush(self) -> bytes:
        """What is left (the stream ended inside a frame)."""
        return b"".join(p.raw for p in self._split.flush())

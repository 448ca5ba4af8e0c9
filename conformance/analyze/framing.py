"""One direction of a TCP connection: its bytes in, iSight frames and typed errors out,
each with the capture's frame numbers (sans-I/O).

The codec's :class:`~conformance.protocol.StreamDecoder` frames the bytes and the
codec judges each frame, so a frame is framed and judged here exactly as the suite
does it everywhere else. Fast path: while no partial frame is waiting, a segment that
holds whole frames is cut where each header says (the decoder's own rule: start word,
version, at most the largest legal frame) and each frame goes straight to the codec's
parser; anything else goes through the decoder (tests/unit/test_analyze_framing.py checks
that both give the same events for every split). A well-formed 14-byte frame (an
answer without blocks: the stream's answers are all alike) is parsed once per reader.

Where the bytes did not start at a frame (the capture began mid-connection) or after a
gap, :class:`FrameReader` first skips to the next plausible header (start word,
version, transfer type and a known action): those bytes are not judged. A frame cut by
a gap or by the capture's end is counted (:attr:`FrameReader.cut`), never judged.

``emit(event, raw, offset, first_frame, last_frame, ts)`` gets every event: ``offset``
counts from the first byte this reader saw, ``first_frame`` is the packet that carried
the frame's first byte, ``last_frame`` and ``ts`` the packet that completed it.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable
from typing import Any

from ..protocol import (
    CLOSED,
    DEFAULT_PROFILE,
    NEED_DATA,
    Profile,
    ProtocolError,
    StreamDecoder,
    TransferType,
    Transport,
    codec_for,
    find_plausible_header,
    frame_spanner,
)
from .snapcut import SnapCut, span_of_prefix

__all__ = ["FrameReader", "plausible_header"]

_TCP = Transport.TCP
_CARRY = 5

Emit = Callable[[Any, bytes, int, int, int, float], None]


def plausible_header(data: bytes, start: int = 0, expect: int | None = None, profile: Profile = DEFAULT_PROFILE) -> int:
    """Index of the first plausible iSight header at or after ``start``: the start word, version 1
    in the profile's byte order, transfer type ``expect`` (or either), a known action. -1 if none."""
    return find_plausible_header(data, start, expect, profile.byte_order)


class FrameReader:
    """Frames of one direction; ``expect`` is the transfer type its sender must use (F3)."""

    def __init__(self, profile: Profile, expect: TransferType, emit: Emit, resync: bool = False) -> None:
        self.profile = profile
        self.expect = expect
        self.emit = emit
        codec = codec_for(profile)
        self._parse = codec.parse
        self._span = frame_spanner(profile.byte_order)  # the one framing rule (protocol/splitter.py)
        self._known: dict[bytes, Any] = {}  # 14-byte frames already parsed (immutable Frames)
        self.decoder = StreamDecoder(profile, expect)
        self.offset = 0  # stream offset of the next byte to read (of the carry, while resynchronising)
        self._buf = bytearray()  # the bytes the decoder has not reported yet
        self._base = 0  # stream offset of _buf[0]
        self._shift = 0  # stream offset minus the decoder's own offset
        self._marks: deque[tuple[int, int]] = deque()  # (stream offset, frame) where each waiting chunk starts
        self.resync = resync
        self._carry = b""
        self.skipped = 0  # bytes skipped, not judged (before a plausible header)
        self.cut = 0  # frames cut by a gap or the capture's end, not judged
        self.eof = False
        self._simple = False
        #: a frame the snap length cut, still running: (its first bytes, stream offset, size, first packet, bytes left)
        self._snapped: tuple[bytes, int, int, int, int] | None = None
        self._settle()

    def _settle(self) -> None:
        """The short path is open when no partial frame waits, nothing is skipped and the stream is open."""
        self._simple = not self._buf and not self.resync and not self.eof and self._snapped is None

    def mark_midstart(self) -> None:
        """The bytes do not start at a frame: skip to the first plausible header."""
        self.resync = True
        self._simple = False

    # -- input -------------------------------------------------------------------------------------
    def feed(self, data: bytes, no: int, ts: float) -> None:
        n = len(data)
        if self._simple and n >= 14 and self._span(data, 0) == n:
            # one whole frame, no partial frame waiting: the codec judges it
            offset = self.offset
            self.offset = offset + n
            event: Any = self._known.get(data) if n == 14 else None
            if event is None:
                try:
                    event = self._parse(data, _TCP, self.expect)
                    if n == 14 and len(self._known) < 256:
                        self._known[data] = event  # an answer without blocks: the same bytes, the same frame
                except ProtocolError as exc:
                    exc.offset += offset
                    event = exc
            self.emit(event, data, offset, no, no, ts)
            return
        self._feed(data, no, ts)

    def _feed(self, data: bytes, no: int, ts: float) -> None:
        if self.eof:
            return
        if self._snapped is not None:
            data = self._snap_rest(len(data), no, ts, data) or b""
            if not data:
                return
        if self.resync:
            data = self._find_header(data)
            if not data:
                return
        if not self._buf:
            n = len(data)
            pos = 0
            span, parse, expect, emit, offset = self._span, self._parse, self.expect, self.emit, self.offset
            while pos < n:
                total = span(data, pos)
                if total <= 0 or pos + total > n:
                    break
                raw = data if total == n else data[pos : pos + total]
                try:
                    event: Any = parse(raw, _TCP, expect)
                except ProtocolError as exc:
                    exc.offset += offset + pos
                    event = exc
                emit(event, raw, offset + pos, no, no, ts)
                pos += total
            if pos == n:
                self.offset = offset + n
                self._settle()
                return
            if pos:
                data = data[pos:]
                self.offset = offset + pos
        dec = self.decoder
        if not dec.buffered:
            self._shift = self.offset - dec.offset
            self._base = self.offset
            self._buf.clear()
            self._marks.clear()
        dec.receive_data(data)
        self._buf += data
        self._marks.append((self.offset, no))
        self.offset += len(data)
        self._drain(no, ts)
        self._settle()

    def close(self, no: int, ts: float) -> None:
        """The sender closed its side (FIN): a frame left incomplete is an F5 error."""
        if self.eof:
            return
        self.eof = True
        if self._snapped is not None:  # the sender closed inside a frame the snap length cut: not judged
            self._snapped = None
            self.cut += 1
        if self.resync:
            self.skipped += len(self._carry)
            self._carry = b""
            self._settle()
            return
        self.decoder.receive_data(b"")
        self._drain(no, ts)
        self._settle()

    def gap(self, nbytes: int) -> None:
        """``nbytes`` are missing here: drop the frame they cut, resynchronise after them."""
        if self.eof:
            return
        if self._snapped is not None:  # a frame the snap length cut, and now bytes missing from it too
            self._snapped = None
            self.cut += 1
        if self.decoder.buffered:
            self.cut += 1
        self.skipped += len(self._carry)
        self.offset += len(self._carry) + nbytes
        self._reset()
        self.resync = True
        self._settle()

    def snap(self, nbytes: int, no: int, ts: float) -> bool:
        """The capture's snap length cut ``nbytes`` of packet ``no`` here: a count at a known place, so the frame
        they cut is a :class:`~.snapcut.SnapCut` when its first bytes tell its length, and framing goes on after
        it. False when they are a gap after all (where the next frame starts is not known)."""
        if self.eof:
            return True
        if self._snapped is not None:
            return self._snap_rest(nbytes, no, ts) is not None
        prefix = bytes(self._buf) if self.decoder.buffered and not self.resync else b""
        start = self._base if prefix else self.offset
        size = span_of_prefix(prefix, self._span)
        if not size:
            self.gap(nbytes)
            return False
        first = self._marks[0][1] if self._marks else no
        self._reset()
        self.offset = start + len(prefix)
        self._snapped = (prefix, start, size, first, size - len(prefix))
        return self._snap_rest(nbytes, no, ts) is not None

    def _snap_rest(self, n: int, no: int, ts: float, data: bytes = b"") -> bytes | None:
        """``n`` more bytes (``data``, or not captured) of the cut frame; when it ends in them it is emitted and
        the rest of ``data`` returned; None when bytes not captured run past its end (a gap: framing resumes
        at the next plausible header)."""
        assert self._snapped is not None
        prefix, start, size, first, left = self._snapped
        take = min(n, left)
        self.offset += take
        if take < left:
            self._snapped = (prefix, start, size, first, left - take)
            return b""
        self._snapped = None
        self.emit(SnapCut(prefix, size, self.profile, start), prefix, start, first, no, ts)
        self._settle()
        if n > take and not data:
            self.gap(n - take)
            return None
        return data[take:]

    def end(self) -> None:
        """The capture ended: a frame still incomplete is cut, not judged."""
        if self._snapped is not None:
            self._snapped = None
            self.cut += 1
        if self.decoder.buffered and not self.eof:
            self.cut += 1
        self.skipped += len(self._carry)
        self._reset()
        self.eof = True
        self._settle()

    # -- internals ------------------------------------------------------------------------------------
    def _reset(self) -> None:
        self.decoder = StreamDecoder(self.profile, self.expect)
        self._buf.clear()
        self._marks.clear()
        self._carry = b""

    def _find_header(self, data: bytes) -> bytes:
        combined = self._carry + data if self._carry else data
        start = self.offset  # stream offset of combined[0]
        pos = plausible_header(combined, 0, int(self.expect), self.profile)
        if pos < 0:
            keep = combined[-_CARRY:] if len(combined) > _CARRY else combined
            self.skipped += len(combined) - len(keep)
            self.offset = start + len(combined) - len(keep)
            self._carry = bytes(keep)
            return b""
        self.skipped += pos
        self.offset = start + pos
        self._carry = b""
        self.resync = False
        return combined[pos:]

    def _drain(self, no: int, ts: float) -> None:
        dec, buf, marks, emit, shift = self.decoder, self._buf, self._marks, self.emit, self._shift
        while True:
            start = dec.offset
            event = dec.next_event()
            if event is NEED_DATA or event is CLOSED:
                break
            begin = start + shift
            end = dec.offset + shift
            raw = bytes(buf[begin - self._base : end - self._base])
            while len(marks) > 1 and marks[1][0] <= begin:
                marks.popleft()
            first = marks[0][1] if marks else no
            if isinstance(event, ProtocolError):
                event.offset += shift
            emit(event, raw, begin, first, no, ts)
        done = dec.offset + shift - self._base
        if done > 0:
            del buf[:done]
            self._base += done
            while len(marks) > 1 and marks[1][0] <= self._base:
                marks.popleft()

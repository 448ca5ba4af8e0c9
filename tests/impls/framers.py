"""How a box cuts a TCP byte stream into frames: four legal choices (R6), sans-I/O.

``feed(data)`` adds bytes; ``events()`` yields what was found, in order:

* ``Frame(data, header)``: a complete frame the framer took whole (its header
  was trusted; the policy still judges it: A5, B1-B5, A3);
* ``Rejected(header)``: a header the framer would not trust (the policy may
  answer it with its action's error when it is a request for a known action);
* ``Garbage(n)``: ``n`` bytes skipped that were no frame;
* ``Close()``: the framer gave up on the connection (close-on-garbage).

Every framer keeps at most one legal frame (``MAX_BODY`` + 14 bytes) plus one read.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass

from .wire import HEADER_LEN, MAX_BODY, ROBOT_TO_BOX, START, Header, known


@dataclass(frozen=True)
class Frame:
    data: bytes
    header: Header


@dataclass(frozen=True)
class Rejected:
    header: Header


@dataclass(frozen=True)
class Garbage:
    size: int


@dataclass(frozen=True)
class Close:
    pass


Event = Frame | Rejected | Garbage | Close


class Framer:
    """Base: a buffer and the scan for the next start word."""

    def __init__(self, extension: bool = True) -> None:
        self.buf = bytearray()
        self.extension = extension
        self.closed = False

    def feed(self, data: bytes) -> None:
        if not self.closed:
            self.buf += data

    def _to_start(self) -> Iterator[Event]:
        """Drop bytes before the next FE FE (keep a trailing FE: it may start one)."""
        at = self.buf.find(START)
        if at < 0:
            keep = 1 if self.buf.endswith(b"\xfe") else 0
            dropped = len(self.buf) - keep
            if dropped:
                del self.buf[:dropped]
                yield Garbage(dropped)
        elif at > 0:
            del self.buf[:at]
            yield Garbage(at)

    def _take(self, header: Header) -> Frame | None:
        size = header.frame_len
        if len(self.buf) < size:
            return None
        data = bytes(self.buf[:size])
        del self.buf[:size]
        return Frame(data, header)

    def events(self) -> Iterator[Event]:
        raise NotImplementedError


class Scanner(Framer):
    """A framer that takes an acceptable header's frame whole and, on any other header,
    drops ``skip_on_reject`` bytes and scans for the next start word."""

    skip_on_reject = 1

    def acceptable(self, h: Header) -> bool:
        raise NotImplementedError

    def events(self) -> Iterator[Event]:
        while not self.closed:
            yield from self._to_start()
            if len(self.buf) < HEADER_LEN:
                return
            h = Header.parse(self.buf)
            if not self.acceptable(h):
                yield Rejected(h)
                del self.buf[: self.skip_on_reject]
                yield Garbage(self.skip_on_reject)
                continue
            frame = self._take(h)
            if frame is None:
                return
            yield frame


class ResyncFine(Scanner):
    """(b) Trust only a header that is a well-shaped request; else resume one byte on.

    A header is taken when start word, version, transfer type, a known action and its
    block shape (B5) are all right: its length is then bounded by 255 pose blocks.
    Anything else is rejected and the scan for FE FE resumes at the header's second
    byte, so a valid frame that begins inside a rejected header is still found.
    """

    def acceptable(self, h: Header) -> bool:
        return h.is_request_start() and h.transfer == ROBOT_TO_BOX and known(h.action, self.extension) and h.shape_ok()


class SkipHeader(ResyncFine):
    """Like :class:`ResyncFine`, but a rejected header's 12 bytes are skipped whole."""

    skip_on_reject = HEADER_LEN


class TrustHeader(Scanner):
    """(a) Trust a header whose start word and version are right and whose announced
    length is plausible (at most 255 pose blocks); skip it as one frame. Implausible
    headers are rejected and the scan resumes one byte on."""

    def acceptable(self, h: Header) -> bool:
        return h.is_request_start() and h.body <= MAX_BODY


class CloseOnGarbage(Framer):
    """(c) Every byte must belong to a request: the stream must start with a header of
    a request for a known action (right start word, version and transfer type), which
    is taken whole. Anything else closes the connection; a request header announcing
    more than 255 pose blocks is rejected (its action's error, A3) and then closed."""

    def events(self) -> Iterator[Event]:
        while not self.closed:
            if not self.buf:
                return
            if self.buf[: len(START)] != START[: len(self.buf)]:
                yield from self._close()
                return
            if len(self.buf) < HEADER_LEN:
                return
            h = Header.parse(self.buf)
            if not h.is_request_start() or h.transfer != ROBOT_TO_BOX or not known(h.action, self.extension):
                yield from self._close()
                return
            if h.body > MAX_BODY:  # a request whose length cannot be right: its error (A3), then close
                yield Rejected(h)
                yield from self._close()
                return
            frame = self._take(h)
            if frame is None:
                return
            yield frame

    def _close(self) -> Iterator[Event]:
        self.closed = True
        yield Garbage(len(self.buf))
        self.buf.clear()
        yield Close()


FRAMERS: dict[str, type[Framer]] = {
    "fine": ResyncFine,
    "skip": SkipHeader,
    "trust": TrustHeader,
    "close": CloseOnGarbage,
}

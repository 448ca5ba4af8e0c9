"""How a box cuts a TCP byte stream into frames, chosen per kind of bad field (R6), sans-I/O.

``feed(data)`` adds bytes; ``events()`` yields what was found, in order:

* ``Frame(data, header)``: a complete frame the framer took whole (its header
  was trusted; the policy still judges it: A5, B1-B5, A3);
* ``Rejected(header)``: a header the framer would not trust (the policy may
  answer it with its action's error when it is a request for a known action);
* ``Garbage(n)``: ``n`` bytes skipped that were no frame;
* ``Close()``: the framer gave up on the connection.

:class:`Framing` says what the framer does with each kind of bad header (the legal
choices of ``conformance/protocol/legal.py``): ``trust`` (take its announced length as
one frame: R6 a, only once start word and version are right and the length is
plausible), ``resume+k`` (reject it and search the next FE FE from its k-th byte: R6 b)
or ``close`` (R6 c: the header is rejected, then the connection closed). Bytes that are
not FE FE where a frame should start are scanned past or close the connection.

Every framer keeps at most one legal frame (``MAX_BODY`` + 14 bytes) plus one read.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, replace

from .wire_format import HEADER_LEN, MAX_BODY, ROBOT_TO_BOX, START, Header, known


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


@dataclass(frozen=True)
class Framing:
    """One framer's choice per kind of bad field (the knobs framing_*)."""

    garbage: str = "scan"  # scan | close
    version: str = "resume+1"  # resume+k | close | frame (no knob: with no blocks, rejected once 14 bytes are read)
    length: str = "resume+1"  # resume+k | close (more than 255 pose blocks announced)
    transfer: str = "trust"  # trust | resume+k | close
    action: str = "trust"  # trust | resume+k | close (an unknown action)
    shape: str = "trust"  # trust | resume+k (a known action whose block type, N or L does not fit)


#: The four framers of earlier rounds, as presets (R6 a, b, b' and c).
PRESETS: dict[str, Framing] = {
    "trust": Framing(),
    "fine": Framing(transfer="resume+1", action="resume+1", shape="resume+1"),
    "skip": Framing(version="resume+12", length="resume+12", transfer="resume+12", action="resume+12",
                    shape="resume+12"),
    "close": Framing(garbage="close", version="close", length="close", transfer="close", action="close"),
}


class Framer:
    """A buffer, the scan for the next start word, and the per-kind choice for each header."""

    def __init__(self, extension: bool = True, framing: Framing | None = None) -> None:
        self.buf = bytearray()
        self.extension = extension
        self.framing = framing or self.preset()
        self.closed = False

    @classmethod
    def preset(cls) -> Framing:
        return PRESETS["trust"]

    def feed(self, data: bytes) -> None:
        if not self.closed:
            self.buf += data

    def parse(self, data: bytearray) -> Header:
        """The header at the start of ``data`` (at least 12 bytes), as this framer reads it."""
        return Header.parse(data)

    def choice(self, h: Header) -> str:
        """What this framer does with the header ``h`` (its start word is right)."""
        f = self.framing
        if h.version != 0x0001:
            return f.version
        if h.body > MAX_BODY:
            return f.length
        if h.transfer != ROBOT_TO_BOX:
            return f.transfer
        if not known(h.action, self.extension):
            return f.action
        if not h.shape_ok():
            return f.shape
        return "trust"

    def events(self) -> Iterator[Event]:
        while not self.closed:
            if self.framing.garbage == "close":
                if self.buf[: len(START)] != START[: len(self.buf)]:
                    yield from self._close()
                    return
            else:
                yield from self._to_start()
            if len(self.buf) < HEADER_LEN:
                return
            h = self.parse(self.buf)
            choice = self.choice(h)
            if choice == "close":
                yield Rejected(h)
                yield from self._close()
                return
            if choice == "frame" and h.frame_len > HEADER_LEN + 2:
                choice = "resume+1"  # a header announcing blocks: rejected at once
            if choice == "frame":  # no blocks announced: rejected once its check field is read (it takes what follows)
                if len(self.buf) < h.frame_len:
                    return
                yield Rejected(h)
                del self.buf[: h.frame_len]
                yield Garbage(h.frame_len)
                continue
            if choice != "trust":
                skip = int(choice.removeprefix("resume+"))
                yield Rejected(h)
                del self.buf[:skip]
                yield Garbage(skip)
                continue
            frame = self._take(h)
            if frame is None:
                return
            yield frame

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

    def _close(self) -> Iterator[Event]:
        self.closed = True
        if self.buf:
            yield Garbage(len(self.buf))
        self.buf.clear()
        yield Close()


class TrustHeader(Framer):
    """(a) Trust a header whose start word and version are right and whose announced
    length is plausible (at most 255 pose blocks); skip it as one frame."""


class ResyncFine(Framer):
    """(b) Trust only a header that is a well-shaped request; else resume one byte on, so a
    valid frame that begins inside a rejected header is still found."""

    @classmethod
    def preset(cls) -> Framing:
        return PRESETS["fine"]


class SkipHeader(Framer):
    """Like :class:`ResyncFine`, but a rejected header's 12 bytes are skipped whole."""

    @classmethod
    def preset(cls) -> Framing:
        return PRESETS["skip"]


class CloseOnGarbage(Framer):
    """(c) Every byte must belong to a request; anything else closes the connection (a request
    header announcing more than 255 pose blocks is first answered with its error, A3)."""

    @classmethod
    def preset(cls) -> Framing:
        return PRESETS["close"]


class LowByteLength(Framer):
    """A defect (``low-byte-length``): the block length read from its low byte only, so L = 0x0119 is taken as 25
    (a C parser that stores bytes 8-9 in a char)."""

    def parse(self, data: bytearray) -> Header:
        header = Header.parse(data)
        return replace(header, length=header.length & 0xFF)


FRAMERS: dict[str, type[Framer]] = {
    "fine": ResyncFine,
    "skip": SkipHeader,
    "trust": TrustHeader,
    "close": CloseOnGarbage,
}

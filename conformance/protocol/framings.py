"""The legal framings of bytes sent to a box, and the answers they explain (R6; sans-I/O).

How a receiver frames bad bytes is its own choice. Every one of these is legal, and a
box may mix them:

* **trust** a header whose start word and version are right: skip its announced length
  as one bad frame (a header announcing more than the largest legal frame may be trusted
  too, its bytes skipped uncounted, R5, so the box waits for them);
* **resynchronise**: reject the header and resume at the next ``FE FE`` found searching
  from any offset after its first byte (1 to 12: a box may skip the whole rejected
  header), so a valid frame that begins inside a rejected header may be answered;
* **close** the connection after bytes that are not a valid request.

:func:`explain` finds the framing that explains what the box did (its answers, in
order, and how the exchange ended) with the fewest broken requirements: MUST first,
then SHOULD, then the fewest departures from the reference framing (which keeps the
messages familiar). A verdict therefore never depends on which legal framing a box
chose: a 0000 is "0000 to malformed input" (R1) only when no legal framing makes it
the answer to a valid frame embedded in the bytes.

The search is a shortest path over (offset, answers used, garbage seen), offsets only
ever growing; a run of bytes that are not a request costs nothing to walk through, so
resuming at the first start word after such bytes is enough (it dominates the longer
skips) and the search stays linear in the bytes.
"""

from __future__ import annotations

import enum
import re
from dataclasses import dataclass, field, replace
from typing import Any

from .answers import Cycle, Expectation, Finding, Rule, rule_for_error, rule_for_frame
from .codec import codec_for
from .constants import CHECK_LEN, HEADER_LEN, MAX_FRAME_LEN, TransferType, Transport
from .errors import LengthError, ProtocolError, StartWordError
from .levels import Level
from .profile import Profile

_START = b"\xfe\xfe"
_FE = b"\xfe"
_NOT_FE = re.compile(b"[^\xfe]")
#: A rejected header is at most this long: a box may resume searching anywhere inside it.
_SKIP = HEADER_LEN


def embedded_actions(data: bytes) -> frozenset[int]:
    """The action byte of every header some legal framing may read in ``data``: one at each start
    word (R6 lets a receiver resume at any FE FE). A probe whose action is none of these cannot be
    mistaken for an answer to a frame embedded in the bytes before it."""
    found, at = set(), data.find(b"\xfe\xfe")
    while 0 <= at and at + 5 < len(data):
        found.add(data[at + 5])
        at = data.find(b"\xfe\xfe", at + 1)
    return frozenset(found)


class End(str, enum.Enum):
    """How the exchange ended after the last answer."""

    ANSWERED = "answered"  # the last answer was the probe's: everything sent was processed
    CLOSED = "closed"  # the box closed or reset the connection
    SILENT = "silent"  # nothing more came within time_out


@dataclass(frozen=True, slots=True)
class Event:
    """One event of the chosen framing: bytes ``start..end`` and the answer attributed to them."""

    start: int
    end: int
    expectation: Expectation
    answer: int | None  # index into the answers, or None (unanswered)


@dataclass
class Explanation:
    findings: list[Finding] = field(default_factory=list)
    events: list[Event] = field(default_factory=list)
    unasked: list[int] = field(default_factory=list)  # answers no event explains
    framing: str = "reference"  # "reference", or how the chosen framing departs from it

    @property
    def must(self) -> list[Finding]:
        return [f for f in self.findings if f.level is Level.MUST]

    @property
    def should(self) -> list[Finding]:
        return [f for f in self.findings if f.level is Level.SHOULD]

    def answers_within(self, start: int, end: int) -> list[int]:
        """The answers attributed to events that begin in bytes ``start..end``."""
        return [e.answer for e in self.events if start <= e.start < end and e.answer is not None]

    def event_at(self, start: int) -> Event | None:
        return next((e for e in self.events if e.start == start), None)


# -- what a receiver sees at an offset -----------------------------------------------------------

VALID, BAD, PENDING = "valid", "bad", "pending"


@dataclass(frozen=True, slots=True)
class Spot:
    """What a receiver sees when it starts a frame at one offset."""

    kind: str  # valid / bad / pending
    exp: Expectation | None = None
    end: int = 0  # valid: end of the frame; bad: where trusting it (or garbage) resumes, -1 when it cannot be trusted
    plausible: bool = False  # a header whose length a receiver may trust
    waits: bool = False  # bad, plausible, incomplete: trusting it means waiting for more bytes
    junk: bool = False  # not a request and not trustable: walking through it costs nothing


class Reader:
    """What a receiver may see at each offset of ``data`` (cached), and where it may go on."""

    def __init__(self, data: bytes, profile: Profile, extension: bool, cycle: Cycle, eof: bool,
                 probe_at: int | None = None) -> None:
        self.data = data
        self.n = len(data)
        self.profile = profile
        self.codec = codec_for(profile)
        self.extension = extension
        self.cycle = cycle
        self.eof = eof
        self.version = codec_for(profile).start[2:]  # version 1 in the profile's byte order
        self._cache: dict[int, Spot] = {}
        self._runs: dict[int, tuple[int, int] | None] = {}
        self.probe_at = probe_at

    def next_start(self, at: int) -> int:
        found = self.data.find(_START, at)
        return self.n if found < 0 else found

    def spot(self, p: int) -> Spot:
        spot = self._cache.get(p)
        if spot is None:
            spot = self._cache[p] = self._classify(p)
        return spot

    def _error(self, error: ProtocolError, **kw: Any) -> Spot:
        exp = rule_for_error(error, self.profile, Transport.TCP, self.extension)
        junk = exp.rule in (Rule.NOT_REQUEST, Rule.ANY) and not kw.get("plausible")
        return Spot(BAD, exp, junk=junk, **kw)

    def _classify(self, p: int) -> Spot:
        data, rem = self.data, self.n - p
        if data[p : p + 2] != _START:
            nxt = self.next_start(p + 1)
            if rem == 1 and data[p] == 0xFE and not self.eof:
                return Spot(PENDING)  # a lone FE may begin a start word
            raw = data[p:nxt]
            return self._error(StartWordError(f"{raw[:2].hex(' ')} where a start word fe fe was expected",
                                              offset=p, raw=raw), end=nxt)
        if rem < HEADER_LEN:
            version = data[p + 2 : p + 4]
            if self.version.startswith(version) and not self.eof:
                return Spot(PENDING)
            if self.eof:
                return self._error(LengthError(f"stream ended inside a frame after {rem} bytes", offset=p,
                                               raw=data[p:]), end=self.n)
            return self._error(ProtocolError(f"version {version.hex(' ')}", offset=p, raw=data[p:], clause="F2"),
                               end=-1)
        header = self.codec.parse_header(data[p : p + HEADER_LEN])
        if header.version != 1:
            return self._error(ProtocolError(f"version 0x{header.version:04X}, expected 0x0001", offset=p,
                                             raw=data[p : p + HEADER_LEN], header=header, clause="F2"), end=-1)
        total = HEADER_LEN + header.body_length + CHECK_LEN
        if total > MAX_FRAME_LEN:
            # a header announcing more than the largest legal frame: like the reference decoder, a box may take
            # it for bytes that are not a request (A5: silence is fine) whatever its action, or trust it (R6 a
            # bounds no length) and skip what it announces, counting rather than buffering (R5): it then waits
            # for those bytes. 0000 is still never allowed
            message = f"header announces {header.body_length} block bytes, more than the largest legal frame"
            try:
                self.codec.check_header(data[p : p + HEADER_LEN], TransferType.ROBOT_TO_BOX)
            except ProtocolError as exc:
                message = exc.message
            return self._error(LengthError(message, offset=p, raw=data[p : p + HEADER_LEN]), end=-1,
                               waits=not self.eof)
        if total > rem:
            try:
                self.codec.check_header(data[p : p + HEADER_LEN], TransferType.ROBOT_TO_BOX)
            except ProtocolError as exc:  # a receiver may reject the header at once, or trust it and wait
                if self.eof:
                    return self._error(exc, end=self.n, plausible=True)
                return self._error(exc, end=-1, plausible=True, waits=True)
            if self.eof:
                return self._error(LengthError(f"stream ended inside a frame after {rem} bytes", offset=p,
                                               raw=data[p:], header=header), end=self.n, plausible=True)
            return Spot(PENDING)
        try:
            frame = self.codec.parse(data[p : p + total], Transport.TCP, TransferType.ROBOT_TO_BOX)
        except ProtocolError as exc:
            return self._error(exc, end=p + total, plausible=True)
        exp = rule_for_frame(frame, self.profile, Transport.TCP, self.extension, self.cycle)
        if p == self.probe_at and exp.valid:
            exp = replace(exp, probe=True, message=f"the valid probe request behind the bytes ({exp.message})")
        if not exp.valid:  # e.g. 26/27 without the extension: a frame, but not a request
            return Spot(BAD, exp, end=p + total, plausible=True)
        return Spot(VALID, exp, end=p + total)

    def garbage(self, p: int) -> bool:
        """The bytes at ``p`` do not begin with a start word."""
        return self.data[p : p + 2] != _START

    def targets(self, p: int) -> list[int]:
        """Where a receiver goes on after the bad bytes at ``p``: past garbage, or the resume targets."""
        spot = self.spot(p)
        if self.garbage(p):
            return [spot.end]
        return ([spot.end] if spot.end >= 0 else []) + [t for t in self.resume_targets(p) if t != spot.end]

    def reference(self, p: int) -> int:
        """Where the reference framing (the codec's StreamDecoder) goes on after bad bytes at ``p``."""
        spot = self.spot(p)
        return spot.end if spot.end >= 0 else self.next_start(p + 2)

    def junk_run(self, p: int) -> tuple[int, int] | None:
        """For junk at ``p`` whose only way on is more junk: (where the run ends, junk events in it).

        Walking a run of bytes that are not a request costs nothing, so a search takes the
        whole run in one step instead of one state per start word (64 KiB of FE stays cheap)."""
        if p in self._runs:
            return self._runs[p]
        chain: list[int] = []
        q = p
        tail: tuple[int, int] | None = None
        while q < self.n:
            stretch = self._fe_stretch(q)
            if stretch > q:
                chain.extend(range(q, stretch))
                q = stretch
                continue
            if not (self.spot(q).kind == BAD and self.spot(q).junk):
                break
            nxt = self.targets(q)
            if len(nxt) != 1:
                break
            chain.append(q)
            q = nxt[0]
            if q in self._runs:
                tail = self._runs[q]
                break
        if not chain:
            self._runs[p] = None
            return None
        exit_at, extra = tail if tail is not None else (q, 0)
        for k, at in enumerate(chain):
            self._runs[at] = (exit_at, len(chain) - k + extra)
        return self._runs[p]

    def _fe_stretch(self, q: int) -> int:
        """Where a stretch of FE bytes from ``q`` stops being uniform junk: each offset before
        it begins a header of FE bytes only (version FEFE, F2, not a request) and goes on only to
        the next, which is one too. ``q`` when there is none, else the last such offset + 1.

        The same answer :meth:`spot` and :meth:`targets` give one offset at a time, without
        classifying each (64 KiB of FE is 64k offsets)."""
        data, width = self.data, HEADER_LEN + 1
        if data[q : q + width] != _FE * width:
            return q
        found = _NOT_FE.search(data, q)
        fe_end = self.n if found is None else found.start()
        return fe_end - HEADER_LEN

    def resume_targets(self, p: int) -> list[int]:
        """Where a receiver that rejects the header at ``p`` may go on: the first start word
        found searching from p+1, p+2, ..., p+12; a target that costs nothing to walk
        through (junk) covers every later one."""
        out: list[int] = []
        at = p + 1
        while True:
            t = self.next_start(at)
            out.append(t)
            if t >= self.n or t >= p + _SKIP or self.spot(t).junk:
                return out
            at = t + 1
            if at > p + _SKIP:
                t = self.next_start(p + _SKIP)
                if t not in out:
                    out.append(t)
                return out

"""The difference between a failing request and the nearest passing one, as data (pure; no sockets here).

A case that failed holds the request the box mishandled. :func:`nearest_valid` writes the valid
request of the same length that differs from it least (the start word, version, transfer type,
block type, count and length a request of its action carries; indexes rising from the profile's
first index; finite values), :func:`differing` lists the bytes where the two differ, grouped by the
field they lie in (:func:`units`: a header field, a block's index, one float value, the check field),
:func:`applied` writes a subset of the failing bytes onto the passing request, and :func:`ddmin`
(Zeller and Hildebrandt's delta debugging) finds a smallest subset that still fails.
"""

from __future__ import annotations

import math
import struct
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import TypeVar

from ..protocol import Codec
from ..protocol.constants import CHECK_LEN, HEADER_FIELDS, HEADER_LEN, START_WORD, VERSION

#: the requests of PROTOCOL.md's core and the length of their blocks (0: none), with their block type
REQUESTS = {0x00: (0, 0), 0x01: (0, 0), 0x02: (0, 0), 0x23: (25, 1), 0x24: (25, 1), 0x25: (5, 2)}
#: a block type's length: the action a frame of unknown action is nearest to
_BY_TYPE = {0: 0x00, 1: 0x23, 2: 0x25}
POSE_PARTS = ("x", "y", "z", "w", "p", "r")
Item = TypeVar("Item")
_WIDE = {name: at for name, (at, width) in HEADER_FIELDS.items() if width == 2}


@dataclass(frozen=True)
class Place:
    """Where a byte lies: a header field, a block's index or value, or the check field."""

    field: str  # a HEADER_FIELDS name, "index", "value" or "check"
    block: int = 0  # 1-based block, for "index" and "value"
    part: int = 0  # 0-based value in the block, for "value"

    def key(self) -> tuple[str, int, int]:
        return self.field, self.block, self.part


def place(offset: int, length: int, block_len: int) -> Place:
    """The place of byte ``offset`` in a frame of ``length`` bytes whose blocks are ``block_len`` long."""
    if offset < HEADER_LEN:
        return next(Place(name) for name, (at, width) in HEADER_FIELDS.items() if at <= offset < at + width)
    if offset >= length - CHECK_LEN or block_len == 0:
        return Place("check")
    block, within = divmod(offset - HEADER_LEN, block_len)
    if within == 0:
        return Place("index", block + 1)
    return Place("value", block + 1, (within - 1) // 4)


def nearest_valid(frame: bytes, codec: Codec) -> bytes | None:
    """The valid request of ``frame``'s length nearest to it (None when no valid request is that long)."""
    if len(frame) < HEADER_LEN + CHECK_LEN:
        return None
    action = frame[5]
    blen = (frame[8] << 8 | frame[9]) if codec.profile.byte_order == "big" else (frame[9] << 8 | frame[8])
    if action not in REQUESTS:  # an unknown action: the request its blocks fit
        guess = _BY_TYPE.get(frame[6], 0x23 if blen == 25 else 0x25 if blen == 5 else 0x00)
        action = guess
    size, btype = REQUESTS[action]
    body = len(frame) - HEADER_LEN - CHECK_LEN
    if (size == 0 and body != 0) or (size and (body == 0 or body % size)):
        return None
    count = body // size if size else 0
    if count > 255:
        return None
    out = bytearray(frame)
    out[0:12] = struct.pack((">" if codec.profile.byte_order == "big" else "<") + "HHBBBBHH", START_WORD, VERSION,
                            0x01, action, btype, count, size, 0)
    first = codec.profile.first_index
    fmt = ">f" if codec.profile.float_byte_order == "big" else "<f"
    for i in range(count):
        at = HEADER_LEN + i * size
        out[at] = (first + i) & 0xFF
        for k in range((size - 1) // 4):
            v = at + 1 + 4 * k
            if not math.isfinite(struct.unpack(fmt, bytes(out[v:v + 4]))[0]):
                out[v:v + 4] = struct.pack(fmt, 1.0)
    out[-2:] = b"\x00\x00"
    return bytes(out)


def differing(failing: bytes, passing: bytes) -> list[int]:
    return [i for i, (a, b) in enumerate(zip(failing, passing)) if a != b] if len(failing) == len(passing) else []


def units(offsets: Sequence[int], length: int, block_len: int) -> list[list[int]]:
    """The differing offsets grouped by the place they lie in, in frame order."""
    groups: dict[tuple[str, int, int], list[int]] = {}
    for o in offsets:
        groups.setdefault(place(o, length, block_len).key(), []).append(o)
    return list(groups.values())


def applied(passing: bytes, failing: bytes, offsets: Sequence[int]) -> bytes:
    out = bytearray(passing)
    for o in offsets:
        out[o] = failing[o]
    return bytes(out)


def ddmin(items: Sequence[Item], fails: Callable[[list[Item]], bool | None], max_tests: int = 24) -> list[Item]:
    """A 1-minimal subset of ``items`` for which ``fails`` is True (given it is True for all of them): Zeller's
    ddmin. ``fails`` returning None (out of time) or the test budget spent stops with what is known to fail."""
    kept = list(items)
    n, tests = 2, 0
    while len(kept) >= 2 and tests < max_tests:
        chunks = [kept[i * len(kept) // n:(i + 1) * len(kept) // n] for i in range(n)]
        chunks = [c for c in chunks if c]
        reduced = False
        tries = chunks + ([[x for x in kept if x not in c] for c in chunks] if n > 2 else [])
        for i, candidate in enumerate(tries):
            tests += 1
            verdict = fails(candidate)
            if verdict is None:
                return kept
            if verdict:  # a chunk: start again in halves; a complement: one chunk fewer
                kept, n, reduced = candidate, 2 if i < len(chunks) else max(n - 1, 2), True
                break
            if tests >= max_tests:
                return kept
        if not reduced:
            if n >= len(kept):
                break
            n = min(len(kept), 2 * n)
    return kept


def float_class(raw: bytes, order: str = "big") -> str:
    """The class of a float32: "NaN", "+infinity", "-infinity", "negative zero", "subnormal", "zero", or ""."""
    v = struct.unpack(">f" if order == "big" else "<f", raw)[0]
    if math.isnan(v):
        return "NaN"
    if math.isinf(v):
        return "+infinity" if v > 0 else "-infinity"
    if v == 0:
        return "negative zero" if math.copysign(1.0, v) < 0 else "zero"
    if abs(v) < 1.1754943508222875e-38:
        return "subnormal"
    return ""


def field_bytes(frame: bytes, name: str) -> bytes:
    at, width = HEADER_FIELDS[name]
    return frame[at:at + width]


def low_high(name: str, byte_order: str) -> tuple[int, int] | None:
    """(offset of the low byte, offset of the high byte) of a 16-bit header field in ``byte_order``."""
    if name not in _WIDE:
        return None
    at = _WIDE[name]
    return (at + 1, at) if byte_order == "big" else (at, at + 1)


@dataclass
class Isolated:
    """What isolation pinned for one failing request."""

    key: tuple[object, ...]  # the same key: the same mechanism (root causes it explains become one)
    title: str
    clauses: tuple[str, ...]
    action: int | None
    repro: tuple[bytes, ...]  # frames on one connection that show it (the passing request with only the difference)
    detail: dict[str, object] = field(default_factory=dict)

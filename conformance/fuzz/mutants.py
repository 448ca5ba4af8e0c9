"""Mutants: cheap cases derived from the cases hypothesis drew, between them (a havoc stage).

Hypothesis pays for every choice it makes (its engine, not the box, is the campaign's
bottleneck: about 0.8 ms of CPU per case drawn against 0.5 ms to send, collect and
judge one). So after every case hypothesis draws, the campaign runs a few *mutants*
of the recent ones, made with a seeded :class:`random.Random` (the campaign's seed
makes them repeat) by protocol-aware operators:

* ``field``: one header field set to one of its boundary or defined values (the
  tables of :mod:`.input_coverage`);
* ``count``: a well-formed block request re-encoded with another block count 1-255
  (its blocks repeated, indexes renumbered): every count reaches the box early;
* ``float``: one float of a block set to one of the float32 classes (±0, subnormals,
  the largest finite, ±infinity, NaNs with and without payload) or to random bits;
* ``bytes``, ``bits``: a few bytes set to 00/01/7F/80/FF or random, a few bits flipped;
* ``cut``, ``grow``: cut at a random point (the oracle's filler completes the frame) or
  random bytes appended;
* ``splice``, ``repeat``: two recent cases in one write, or the same frame 2-4 times.

A UDP parent gives a UDP datagram (its CRC recomputed half the time). A mutant whose
first header announces more than the largest legal frame is not sent (a box that trusts
the header would wait time_out for it: R5's own cases test that). Every mutant is a
full case: its probe, the oracle's judgement, liveness, coverage. A failing one is
confirmed and, as it was not drawn by hypothesis, searched for again with its clause's
plain strategy (:meth:`.triage.Triage.settle`).
"""

from __future__ import annotations

import dataclasses
import random
from collections import deque
from collections.abc import Callable

from ..protocol import BLOCK_LEN, HEADER_LEN, MAX_FRAME_LEN, BlockType, Transport
from ..protocol.constants import CHECK_LEN, START_WORD, VERSION
from .input_coverage import FIELDS, field_space
from .strategies import EDGE_FINITE_BITS, NON_FINITE_BITS, FuzzCase, Strategies

#: Recent hypothesis cases kept as parents.
PARENTS = 64
#: Byte values the ``bytes`` operator prefers.
SPECIAL_BYTES = (0x00, 0x01, 0x7F, 0x80, 0xFF, 0xFE)
#: Block counts the ``count`` operator prefers (else any 1-255).
EDGE_COUNTS = (1, 2, 7, 8, 15, 16, 17, 31, 32, 63, 64, 127, 128, 200, 254, 255)
#: The largest body a header may announce (beyond it a trusting box waits time_out).
MAX_BODY = MAX_FRAME_LEN - HEADER_LEN - CHECK_LEN
FLOAT_BLOCKS = (BlockType.POSE, BlockType.TOLERANCE)

Op = Callable[[bytes, Transport], tuple[bytes, str] | None]


class Mutants:
    """Mutants of the recent hypothesis cases (see the module docstring)."""

    def __init__(self, strategies: Strategies, seed: int) -> None:
        self.s = strategies
        self.codec = strategies.codec
        self.rng = random.Random(seed)
        self.parents: deque[FuzzCase] = deque(maxlen=PARENTS)
        self.space = field_space()
        self.fields = [name for name, _off, _width, _defined in FIELDS]
        self.ops: list[tuple[str, Op]] = [
            ("field", self._field), ("count", self._count), ("float", self._float), ("bytes", self._bytes),
            ("bits", self._bits), ("cut", self._cut), ("grow", self._grow), ("splice", self._splice),
            ("repeat", self._repeat),
        ]
        self.made = 0

    def feed(self, case: FuzzCase) -> None:
        """A case hypothesis drew: a parent for the next mutants when it is one frame whose start word and version
        are right and whose length is what its header announces (not garbage, a splice or a truncated or split
        frame: a mutant of those often has a framing a box may legally read otherwise, and then waits time_out)."""
        data = case.data
        if case.eof or case.splits or not HEADER_LEN <= len(data) <= MAX_FRAME_LEN:
            return
        header = self.codec.parse_header(data)
        if (header.start_word, header.version) == (START_WORD, VERSION) and self.codec.frame_length(data) == len(data):
            self.parents.append(case)

    def next(self) -> FuzzCase | None:
        """The next mutant (None before the first parent, or when no operator applied to the parent picked)."""
        if not self.parents:
            return None
        rng = self.rng
        parent = self.parents[-1] if rng.random() < 0.5 else rng.choice(self.parents)
        for _ in range(8):  # an operator may not apply to the parent (a count change of a NONE request)
            name, op = rng.choice(self.ops)
            got = op(parent.data, parent.transport)
            if got is None or not self._sendable(got[0]):
                continue
            data, what = got
            self.made += 1
            case = self.s.case("mutant", "", data, f"{what} (a mutant of a {parent.kind} case)", parent.transport)
            return dataclasses.replace(case, clause=case.first_clause)
        return None

    # -- helpers -----------------------------------------------------------------------
    def _sendable(self, data: bytes) -> bool:
        if len(data) > 2 * MAX_FRAME_LEN:
            return False
        if len(data) < HEADER_LEN:
            return True
        return self.codec.parse_header(data).body_length <= MAX_BODY

    def _checked(self, data: bytes, transport: Transport) -> bytes:
        """A UDP datagram's CRC recomputed half the time (else it stays as mutated: R7)."""
        if transport is Transport.UDP and len(data) > CHECK_LEN and self.rng.random() < 0.5:
            return data[:-CHECK_LEN] + self.codec.check_bytes(data[:-CHECK_LEN])
        return data

    # -- operators ---------------------------------------------------------------------
    def _field(self, data: bytes, transport: Transport) -> tuple[bytes, str] | None:
        if len(data) < HEADER_LEN:
            return None
        name = self.rng.choice(self.fields)
        value = self.rng.choice(self.space[name])
        header = dataclasses.replace(self.codec.parse_header(data), **{name: value})
        out = self.codec.encode_header(header) + data[HEADER_LEN:]
        return self._checked(out, transport), f"header field {name} set to {value:#x}"

    def _count(self, data: bytes, transport: Transport) -> tuple[bytes, str] | None:
        if len(data) < HEADER_LEN:
            return None
        header = self.codec.parse_header(data)
        bt = header.block_type
        if bt not in FLOAT_BLOCKS or header.block_length != BLOCK_LEN[BlockType(bt)] or not header.block_count:
            return None
        per = header.block_length - 1
        raw = b"".join(data[at + 1 : at + 1 + per] for at in range(HEADER_LEN, HEADER_LEN + header.body_length,
                                                                    header.block_length))[: 4 * per]
        rng = self.rng
        n = rng.choice(EDGE_COUNTS) if rng.random() < 0.5 else rng.randint(1, 255)
        header = dataclasses.replace(header, block_count=n)
        out = self.s.raw(header, self.s.blocks(bt, n, raw, finite=False), transport=transport)
        return out, f"re-encoded with {n} blocks"

    def _float(self, data: bytes, transport: Transport) -> tuple[bytes, str] | None:
        if len(data) < HEADER_LEN:
            return None
        header = self.codec.parse_header(data)
        if header.block_type not in FLOAT_BLOCKS or header.block_length not in (5, 25) or not header.block_count:
            return None
        rng = self.rng
        end = min(len(data) - CHECK_LEN, HEADER_LEN + header.body_length)
        blocks = (end - HEADER_LEN) // header.block_length
        if blocks < 1:
            return None
        words = (header.block_length - 1) // 4
        at = HEADER_LEN + rng.randrange(blocks) * header.block_length + 1 + 4 * rng.randrange(words)
        bits = rng.choice(EDGE_FINITE_BITS + NON_FINITE_BITS) if rng.random() < 0.7 else rng.getrandbits(32)
        out = data[:at] + self.s._u32(bits) + data[at + 4 :]  # noqa: SLF001 - the profile's float packing
        return self._checked(out, transport), f"a float set to bits {bits:08x}"

    def _bytes(self, data: bytes, transport: Transport) -> tuple[bytes, str] | None:
        out = bytearray(data)
        rng = self.rng
        for _ in range(rng.randint(1, 4)):
            out[rng.randrange(len(out))] = rng.choice(SPECIAL_BYTES) if rng.random() < 0.5 else rng.getrandbits(8)
        return self._checked(bytes(out), transport), "a few bytes set"

    def _bits(self, data: bytes, transport: Transport) -> tuple[bytes, str] | None:
        out = bytearray(data)
        for _ in range(self.rng.randint(1, 3)):
            bit = self.rng.randrange(8 * len(out))
            out[bit // 8] ^= 1 << (bit % 8)
        return bytes(out), "a few bits flipped"

    def _cut(self, data: bytes, transport: Transport) -> tuple[bytes, str] | None:
        if len(data) < 2:
            return None
        at = self.rng.randrange(1, len(data))
        return data[:at], f"cut after {at} bytes"

    def _grow(self, data: bytes, transport: Transport) -> tuple[bytes, str] | None:
        extra = self.rng.randbytes(self.rng.randint(1, 16))
        return data + extra, f"{len(extra)} random bytes appended"

    def _splice(self, data: bytes, transport: Transport) -> tuple[bytes, str] | None:
        other = self.rng.choice(self.parents)
        if transport is Transport.UDP or other.transport is not transport:
            return None
        return data + other.data, f"followed by a {other.kind} case in the same write"

    def _repeat(self, data: bytes, transport: Transport) -> tuple[bytes, str] | None:
        if transport is Transport.UDP:
            return None
        k = self.rng.randint(2, 4)
        return data * k, f"repeated {k} times in one write"


__all__ = ["EDGE_COUNTS", "MAX_BODY", "PARENTS", "Mutants"]

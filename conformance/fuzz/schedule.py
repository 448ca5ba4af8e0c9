"""Boundaries first: a deterministic list of cases a campaign sends early, interleaved with hypothesis's.

Random strategies reach a single block count, field value or float class only by
luck (a crash behind exactly 7 blocks was missed in 170,000 random cases). So, like
boofuzz walks every field's boundaries, a campaign also walks a fixed schedule, one
scheduled case after each hypothesis case, until it is done (a few thousand cases:
seconds at the usual rate). The groups are taken in turn, so the small ones finish first:

* **counts**: a well-formed pose, register-pose and tolerance request of every block
  count 1-255, with correct indexes and finite values (boundary counts first: 1, 2, 3,
  4, 7, 8, 9, ... 254, 255, then the rest);
* **indexes**: one wrong block index at the first, second, 17th, 129th and last block (B3);
* **fields**: every header field at each of its boundary values (:func:`.input_coverage.field_space`),
  on a NONE and on a one-pose request;
* **values**: every float32 class of :data:`FLOAT_SPECIALS` (±0, subnormals, NaN with
  payloads, ±inf, huge magnitudes, the largest finite) in a pose and a tolerance request,
  and ProgIdx's int32 edges with extension E;
* **sizes**: garbage of every power-of-two size up to 100,000 bytes, the largest legal
  frame and one byte more, and headers announcing more than the largest legal frame
  followed by the whole body;
* **udp** (with a UDP target): datagrams of the boundary counts, and one with a wrong CRC.

The cases carry the oracle's expectations like any other (they are built with
:meth:`Strategies.case`), so they are judged the same way.
"""

from __future__ import annotations

import dataclasses
import random
from collections.abc import Iterator

from ..protocol import BLOCK_LEN, MAX_FRAME_LEN, REQUEST_SHAPE, Action, BlockType, Header, Transport
from ..protocol.constants import MAX_BLOCK_COUNT
from .input_coverage import EDGES_U8, FIELDS, field_space
from .strategies import BLOCK_ACTIONS, FuzzCase, Strategies

#: float32 bit patterns of every class, legal and not (B4).
FLOAT_SPECIALS = (
    0x00000000, 0x80000000,  # ±0
    0x00000001, 0x80000001, 0x007FFFFF, 0x807FFFFF,  # subnormals
    0x00800000, 0x80800000,  # smallest normals
    0x7149F2CA, 0xF149F2CA,  # ±1e30
    0x7F7FFFFF, 0xFF7FFFFF,  # largest finite
    0x7F800000, 0xFF800000,  # ±inf
    0x7FC00000, 0xFFC00000, 0x7FC00001, 0x7FFFFFFF, 0xFFFFFFFF,  # quiet NaNs, payloads, negative
    0x7F800001, 0x7FA5A5A5, 0xFF800001,  # signalling NaNs
)
#: ProgIdx values (E2): int32 edges.
INT32_EDGES = (0, 1, -1, 2, 255, 256, 409, 2**15, 2**31 - 1, -(2**31), -(2**31) + 1)
#: Garbage sizes: every power of two and its neighbours up to 64 KiB, the largest legal frame ±1, 100,000.
GARBAGE_SIZES = tuple(sorted({1, 2, 3, 7, 8, 9, 13, 14, 15, 64, 65, 255, 256, 1024, 4096, 8192, 16384, 32768,
                              65535, 65536, 100_000, MAX_FRAME_LEN - 1, MAX_FRAME_LEN, MAX_FRAME_LEN + 1}))


#: A long pause mid-frame (R3: the frame still counts as one).
PAUSE_S = 0.15


def boundary_counts() -> list[int]:
    """1-255, the boundary counts first."""
    first = [c for c in EDGES_U8 if c >= 1]
    return first + [c for c in range(1, MAX_BLOCK_COUNT + 1) if c not in first]


class Schedule:
    """The scheduled cases, in the order they are sent (``next()`` gives None once done)."""

    def __init__(self, s: Strategies) -> None:
        self.s = s
        groups = [self._indexes(), self._fields(), self._values(), self._sizes(), self._splits(), self._counts()]
        if s.udp:
            groups.append(self._udp())
        self._iter = _round_robin(groups)
        self.sent = 0
        self.done = False

    def next(self) -> FuzzCase | None:
        if self.done:
            return None
        case = next(self._iter, None)
        if case is None:
            self.done = True
        else:
            self.sent += 1
        return case

    def __iter__(self) -> Iterator[FuzzCase]:
        while (case := self.next()) is not None:
            yield case

    # -- building ----------------------------------------------------------------------------
    def request(self, action: Action, n: int, salt: int = 0, transport: Transport = Transport.TCP,
                indexes: list[int] | None = None) -> bytes:
        """A request of ``n`` blocks with finite values, and correct indexes unless ``indexes`` are given."""
        s = self.s
        shape = REQUEST_SHAPE[action]
        bt = int(shape.block_type)
        per = BLOCK_LEN[shape.block_type]
        raw = random.Random(n * 1009 + int(action) * 31 + salt).randbytes(4 * max(0, per - 1))
        body = s.blocks(bt, n, raw, indexes) if n else b""
        return s.raw(Header(action=action, block_type=bt, block_count=n, block_length=per), body, transport=transport)

    def _indexes(self) -> Iterator[FuzzCase]:
        """B3: one wrong index at the first block, the second, the 17th and the 129th (what a counter
        wrapping at 16 or 128 expects there) and the last: a parse error, never 0000."""
        first = self.s.first
        for n, position, wrong in ((1, 0, first ^ 1), (2, 1, first + 2), (17, 16, (first + 16) & 0x0F),
                                   (129, 128, (first + 128) & 0x7F), (255, 254, first + 255)):
            for action in BLOCK_ACTIONS:
                indexes = [(first + i) & 0xFF for i in range(n)]
                indexes[position] = wrong & 0xFF
                yield self.s.case("edge-index", "B3", self.request(action, n, indexes=indexes),
                                  f"{action.name} ×{n}, index {wrong & 0xFF:02x} at block {position + 1}")

    def _counts(self) -> Iterator[FuzzCase]:
        for n in boundary_counts():
            for action in BLOCK_ACTIONS:
                yield self.s.case("valid-count", "", self.request(action, n), f"{action.name} ×{n} (every count)")

    def _fields(self) -> Iterator[FuzzCase]:
        """Every field's boundary values, the fields taken in turn (each field's edges come early)."""
        return _round_robin([self._field(name, off, width) for name, off, width, _defined in FIELDS])

    def _field(self, name: str, off: int, width: int) -> Iterator[FuzzCase]:
        s = self.s
        bases = [(Action.NONE, self.request(Action.NONE, 0)), (Action.POSE, self.request(Action.POSE, 1))]
        order = s.profile.byte_order
        for value in field_space()[name]:
            for action, base in bases:
                data = bytearray(base)
                data[off : off + width] = value.to_bytes(width, order)
                if bytes(data) == base:
                    continue
                yield s.case(f"edge-{name}", _FIELD_CLAUSE[name], bytes(data),
                             f"{action.name} with {name} {value:#0{2 + 2 * width}x} (a boundary value)")

    def _values(self) -> Iterator[FuzzCase]:
        s = self.s
        for bits in FLOAT_SPECIALS:
            word = s._u32(bits)
            for action in BLOCK_ACTIONS:
                n = 1 if action is not Action.TOLERANCE else 2
                data = bytearray(self.request(action, n))
                per = BLOCK_LEN[REQUEST_SHAPE[action].block_type]
                for b in range(n):  # every value word of every block
                    for w in range(12 + b * per + 1, 12 + (b + 1) * per, 4):
                        data[w : w + 4] = word
                yield s.case("edge-float", "B4", bytes(data), f"{action.name} ×{n}, every value {bits:08x}")
        if s.extension:
            for value in INT32_EDGES:
                body = bytes([s.first]) + value.to_bytes(4, s.order, signed=True)
                header = Header(action=Action.PROG_IDX, block_type=BlockType.VALUE, block_count=1, block_length=5)
                yield s.case("edge-progidx", "", s.raw(header, body), f"ProgIdx {value} (an int32 edge)")

    def _sizes(self) -> Iterator[FuzzCase]:
        s = self.s
        for size in GARBAGE_SIZES:
            data = bytearray(random.Random(size).randbytes(size))
            if data[:1] == b"\xfe":
                data[0] = 0x55
            yield s.case("edge-garbage", "F1", bytes(data), f"{size} bytes of garbage")
        for n, length in ((MAX_BLOCK_COUNT, 26), (MAX_BLOCK_COUNT, 257), (26, 246)):
            header = Header(action=Action.POSE, block_type=BlockType.POSE, block_count=n, block_length=length)
            body = random.Random(n * length).randbytes(n * length)
            yield s.case("edge-oversized", "R5", s.raw(header, body),
                         f"POSE header announcing {n}×{length} = {n * length} bytes, then all of them")

    def _splits(self) -> Iterator[FuzzCase]:
        """R3: a one-pose request cut at every offset (2 ms pause), then a few long pauses mid-frame."""
        s = self.s
        data = self.request(Action.POSE, 1)
        for cut, gap in [(c, 0.002) for c in range(1, len(data))] + [(c, PAUSE_S) for c in (2, 7, 12, 20)]:
            case = s.case("R3-split", "R3", data, f"POSE ×1 split at {cut}, {gap * 1000:g} ms pause")
            yield dataclasses.replace(case, splits=(cut,), gap_s=gap)

    def _udp(self) -> Iterator[FuzzCase]:
        s, udp = self.s, Transport.UDP
        for n in [c for c in EDGES_U8 if c >= 1]:
            for action in BLOCK_ACTIONS:
                yield s.case("F7-valid", "", self.request(action, n, transport=udp), f"{action.name} ×{n} datagram", udp)
        frame = self.request(Action.NONE, 0, transport=udp)
        yield s.case("F7-crc", "F7", frame[:-2] + bytes([frame[-2] ^ 0xFF, frame[-1]]), "NONE datagram, wrong CRC", udp)


_FIELD_CLAUSE = {"start_word": "F1", "version": "F2", "transfer_type": "F3", "action": "A5", "block_type": "B5",
                 "block_count": "B5", "block_length": "B5", "error_code": "A3"}


def _round_robin(groups: list[Iterator[FuzzCase]]) -> Iterator[FuzzCase]:
    live = list(groups)
    while live:
        for g in list(live):
            case = next(g, None)
            if case is None:
                live.remove(g)
            else:
                yield case


__all__ = ["FLOAT_SPECIALS", "GARBAGE_SIZES", "INT32_EDGES", "Schedule", "boundary_counts"]

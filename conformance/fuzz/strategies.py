"""Hypothesis strategies for fuzz cases: valid requests, and malformed ones by the clause they break.

Every strategy draws a :class:`FuzzCase`: the bytes, the clause it means to break
(``kind`` names the strategy, e.g. ``"B3-index"``), and the oracle's expectations for
those bytes (:func:`~conformance.fuzz.oracle.expectations`: A3's error where PROTOCOL.md
names one, else "never 0000"). Strategies are built for one profile (first index,
byte orders, CRC) and know whether the box implements extension E.

Shrinking: every choice is ordered so that hypothesis's shrinker moves towards the
smallest, most readable frame: ``sampled_from`` lists start with action NONE, counts
start at the fewest blocks, float values shrink to 0.0, bodies to zero bytes, and
:meth:`Strategies.cases` lists the categories simplest first (a valid request, then
one broken header field, ... then byte-level mutation and raw garbage).
"""

from __future__ import annotations

import dataclasses
import struct
from collections.abc import Callable

from hypothesis import strategies as st

from ..protocol import (
    BLOCK_LEN,
    REQUEST_SHAPE,
    Action,
    BlockType,
    Header,
    Profile,
    Transport,
    codec_for,
    peek_header,
)
from ..protocol.constants import MAX_BLOCK_COUNT, MAX_FRAME_LEN, START_WORD
from .case import FuzzCase, _finite
from .oracle import expectations

#: IEEE-754 binary32 edge values that are legal (B4): a conforming box accepts them.
EDGE_FINITE_BITS = (
    0x80000000,  # -0.0
    0x00000001,  # smallest subnormal 1.4e-45
    0x80000001,  # its negative
    0x007FFFFF,  # largest subnormal
    0x00800000,  # smallest normal 1.18e-38
    0x7F7FFFFF,  # largest finite 3.4e38
    0xFF7FFFFF,  # most negative finite
)
#: NaN and infinity (B4: SHOULD be a parse error in a strict profile).
NON_FINITE_BITS = (0x7F800000, 0xFF800000, 0x7FC00000, 0xFFC00000, 0x7F800001, 0x7FFFFFFF)
#: Actions a valid request may carry, simplest first (26/27 only with extension E).
CORE_ACTIONS = (Action.NONE, Action.CYCLE_ON, Action.CYCLE_OFF, Action.POSE, Action.REGISTER_POSE, Action.TOLERANCE)
BLOCK_ACTIONS = (Action.POSE, Action.REGISTER_POSE, Action.TOLERANCE)
#: Block counts of valid frames: 1 first (shrinking), 255 = the largest legal frame.
SMALL_COUNT = 4
COUNTS = (1, 2, 3, 4, 255)
#: Pauses between the pieces of a split frame (R3).
GAPS = (0.0, 0.001, 0.002, 0.005)


def _skip(excluded: int) -> Callable[[int], int]:
    """Map 0..max-1 onto 0..max without ``excluded`` (a filter that never rejects)."""
    return lambda v: v if v < excluded else v + 1


class Strategies:
    """Fuzz-case strategies for one profile.

    Hypothesis pays about 30-40 µs per choice it makes (measured: see docs/FUZZING.md),
    so every case is drawn with few choices: the values of all blocks of a frame come
    from one ``binary`` draw (turned finite where a valid frame needs it), counts from
    one ``sampled_from``, excluded values are skipped arithmetically instead of filtered.
    Strategy objects are built once here, never inside a draw.
    """

    def __init__(self, profile: Profile, extension: bool = True, udp: bool = False) -> None:
        self.profile = profile
        self.extension = extension
        self.udp = udp
        self.codec = codec_for(profile)
        self.order = profile.float_byte_order
        self._u32 = struct.Struct((">" if self.order == "big" else "<") + "I").pack
        self.first = profile.first_index
        self.actions = CORE_ACTIONS + ((Action.PROG_IDX, Action.VISION_RESULT) if extension else ())
        known = sorted({int(a) for a in self.actions})
        unknown = [a for a in range(256) if a not in known]
        self._action = st.sampled_from(self.actions)
        self._block_action = st.sampled_from(BLOCK_ACTIONS + ((Action.PROG_IDX,) if extension else ()))
        self._float_action = st.sampled_from(BLOCK_ACTIONS)
        self._unknown_action = st.integers(0, len(unknown) - 1).map(unknown.__getitem__)
        # the usual counts first (shrinking), else any count 1-255 (a box may fail at exactly 7 blocks)
        self._counts = st.one_of(st.sampled_from(COUNTS), st.integers(1, MAX_BLOCK_COUNT))
        self._small = st.integers(1, SMALL_COUNT)
        self._binary: dict[int, st.SearchStrategy[bytes]] = {}
        self._request = _request(self)
        self._specials = st.sampled_from(EDGE_FINITE_BITS + NON_FINITE_BITS)
        self._edits = st.binary(min_size=4, max_size=12)

    # -- building ------------------------------------------------------------------------
    def case(self, kind: str, clause: str, data: bytes, note: str, transport: Transport = Transport.TCP,
             eof: bool = False) -> FuzzCase:
        filler, expects = expectations(data, self.profile, transport, self.extension, eof)
        return FuzzCase(kind, clause, data, note, transport, eof, filler, expects)

    def raw(self, header: Header, body: bytes = b"", check: bytes | None = None,
            transport: Transport = Transport.TCP) -> bytes:
        return self.codec.encode_raw(header, body, check, transport)

    def binary(self, size: int) -> st.SearchStrategy[bytes]:
        """Exactly ``size`` bytes (one choice; shrinks to zeros)."""
        found = self._binary.get(size)
        if found is None:
            found = self._binary[size] = st.binary(min_size=size, max_size=size)
        return found

    def blocks(self, block_type: int, n: int, raw: bytes, indexes: list[int] | None = None,
               finite: bool = True) -> bytes:
        """n blocks from the value bytes of the first few (repeated: cheap for 255 blocks)."""
        if not n or block_type not in (BlockType.POSE, BlockType.TOLERANCE, BlockType.VALUE):
            return b""
        per = BLOCK_LEN[BlockType(block_type)] - 1
        if finite and block_type != BlockType.VALUE:
            raw = _finite(raw, self.order)
        k = max(1, min(n, SMALL_COUNT))
        values = [raw[i * per : (i + 1) * per].ljust(per, b"\0") for i in range(k)]
        idx = indexes if indexes is not None else [(self.first + i) & 0xFF for i in range(n)]
        return b"".join(bytes([i]) + values[j % k] for j, i in enumerate(idx))

    def value_bytes(self, block_type: int, n: int) -> st.SearchStrategy[bytes]:
        if not n or block_type not in BLOCK_LEN or not BLOCK_LEN[BlockType(block_type)]:
            return self.binary(0)
        return self.binary(min(n, SMALL_COUNT) * (BLOCK_LEN[BlockType(block_type)] - 1))

    def _field(self, kind: str, clause: str, name: str, values: st.SearchStrategy[int], label: str) -> st.SearchStrategy[FuzzCase]:
        """A valid request with one header field replaced."""
        return st.tuples(self._request, values).map(
            lambda hv: self.case(kind, clause, self.raw(dataclasses.replace(hv[0][0], **{name: hv[1]}), hv[0][1]),
                                 f"{label} {hv[1]:#x} on a {Action(hv[0][0].action).name} request")
        )

    # -- the categories --------------------------------------------------------------------
    def valid(self) -> st.SearchStrategy[FuzzCase]:
        return self._request.map(
            lambda hb: self.case("valid", "", self.raw(*hb), f"{Action(hb[0].action).name} ×{hb[0].block_count}")
        )

    def start_word(self) -> st.SearchStrategy[FuzzCase]:
        return self._field("F1-start-word", "F1", "start_word", st.integers(0, 0xFFFE).map(_skip(START_WORD)), "start word")

    def version(self) -> st.SearchStrategy[FuzzCase]:
        return self._field("F2-version", "F2", "version", st.integers(0, 0xFFFE).map(_skip(1)), "version")

    def direction(self) -> st.SearchStrategy[FuzzCase]:
        values = st.one_of(st.just(0x10), st.integers(0, 254).map(_skip(1)))
        return self._field("F3-direction", "F3", "transfer_type", values, "transfer type")

    def unknown_action(self) -> st.SearchStrategy[FuzzCase]:
        return self._field("A5-unknown-action", "A5", "action", self._unknown_action, "action")

    def request_error_field(self) -> st.SearchStrategy[FuzzCase]:
        return self._field("A3-request-error-field", "A3", "error_code", st.integers(1, 0xFFFF), "error field")

    def shape(self) -> st.SearchStrategy[FuzzCase]:
        return _shape(self)

    def index(self) -> st.SearchStrategy[FuzzCase]:
        return _index(self)

    def floats(self) -> st.SearchStrategy[FuzzCase]:
        return _floats(self)

    def truncated(self) -> st.SearchStrategy[FuzzCase]:
        return _truncated(self, spliced=False)

    def spliced(self) -> st.SearchStrategy[FuzzCase]:
        return _truncated(self, spliced=True)

    def trailing(self) -> st.SearchStrategy[FuzzCase]:
        return st.tuples(self._request, st.binary(min_size=1, max_size=8)).map(
            lambda he: self.case("F5-trailing", "F5", self.raw(*he[0]) + he[1],
                                 f"{Action(he[0][0].action).name} followed by {len(he[1])} extra bytes")
        )

    def tcp_check(self) -> st.SearchStrategy[FuzzCase]:
        """F6: a TCP check field holding the CRC (SHOULD be accepted; drawn as 00 00) or any other value."""

        def build(hc: tuple[tuple[Header, bytes], bytes]) -> FuzzCase:
            (header, body), check = hc
            crc = self.codec.check_bytes(self.codec.encode_header(header) + body)
            check = check if check != b"\0\0" else crc
            what = "its CRC" if check == crc else check.hex(" ")
            note = f"{Action(header.action).name} with TCP check field {what}"
            return self.case("F6-check", "F6", self.raw(header, body, check), note)

        return st.tuples(self._request, self.binary(2)).map(build)

    def split(self) -> st.SearchStrategy[FuzzCase]:
        """R3: a valid request written in up to three pieces, with a pause between them."""

        def build(hc: tuple[tuple[Header, bytes], bytes, float]) -> FuzzCase:
            data = self.raw(*hc[0])
            cuts = tuple(sorted({1 + c % (len(data) - 1) for c in hc[1]}))
            case = self.case("R3-split", "R3", data, f"{Action(hc[0][0].action).name} split at {list(cuts)}")
            return dataclasses.replace(case, splits=cuts, gap_s=hc[2])

        return st.tuples(self._request, st.binary(min_size=1, max_size=3), st.sampled_from(GAPS)).map(build)

    def oversized(self) -> st.SearchStrategy[FuzzCase]:
        return _oversized(self)

    def mutated(self) -> st.SearchStrategy[FuzzCase]:
        return _mutated(self)

    def garbage(self) -> st.SearchStrategy[FuzzCase]:
        """Random bytes: up to 64 drawn, or a drawn pattern repeated up to beyond the largest legal frame."""
        short = st.binary(min_size=1, max_size=64)
        long = st.tuples(st.integers(65, 4 * MAX_FRAME_LEN), short).map(lambda sp: (sp[1] * sp[0])[: sp[0]])
        return st.one_of(short, long).map(lambda b: self.case("F1-garbage", "F1", b, f"{len(b)} bytes of garbage"))

    def datagram(self) -> st.SearchStrategy[FuzzCase]:
        return _datagram(self)

    # -- everything --------------------------------------------------------------------------
    def categories(self) -> dict[str, Callable[[], st.SearchStrategy[FuzzCase]]]:
        """Name -> strategy, simplest first (the order shrinking prefers)."""
        cats: dict[str, Callable[[], st.SearchStrategy[FuzzCase]]] = {
            "valid": self.valid, "F1-start-word": self.start_word, "F2-version": self.version,
            "F3-direction": self.direction, "A5-unknown-action": self.unknown_action, "B5-shape": self.shape,
            "B3-index": self.index, "B4-floats": self.floats, "F5-trailing": self.trailing,
            "F5-spliced": self.spliced, "F5-truncated": self.truncated, "F6-check": self.tcp_check,
            "A3-request-error-field": self.request_error_field, "R3-split": self.split, "R5-oversized": self.oversized,
            "mutation": self.mutated, "F1-garbage": self.garbage,
        }
        if self.udp:
            cats["F7-udp"] = self.datagram
        return cats

    def cases(self, only: tuple[str, ...] = ()) -> st.SearchStrategy[FuzzCase]:
        """Any fuzz case (or only the named categories)."""
        cats = self.categories()
        unknown = [n for n in only if n not in cats]
        if unknown:
            raise ValueError(f"unknown fuzz categories {unknown}; choose from {', '.join(cats)}")
        return st.one_of([make() for name, make in cats.items() if not only or name in only])


# -- composite strategies (module level: built once per Strategies, never inside a draw) ----------


def _shape_of(action: int) -> tuple[int, int, int, int]:
    shape = REQUEST_SHAPE[Action(action)]
    return int(shape.block_type), shape.low, shape.high, BLOCK_LEN[shape.block_type]


@st.composite
def _request(draw: st.DrawFn, s: Strategies) -> tuple[Header, bytes]:
    """A well-formed request as (header, body)."""
    action = draw(s._action)
    bt, low, high, length = _shape_of(action)
    n = (draw(s._counts) if high > 1 else 1) if high else 0
    body = s.blocks(bt, n, draw(s.value_bytes(bt, n))) if n else b""
    return Header(action=action, block_type=bt, block_count=n, block_length=length), body


@st.composite
def _shape(draw: st.DrawFn, s: Strategies) -> FuzzCase:
    """B5/B1/B2/E1: block type, count or length not what the action needs."""
    action = draw(s._action)
    want_bt, low, high, want_len = _shape_of(action)
    bt, n, length = want_bt, low, want_len
    which = draw(st.sampled_from(("count", "length", "type")))
    if which == "type":
        bt = draw(st.integers(0, 254).map(_skip(want_bt)))
    elif which == "count":
        bad = [c for c in range(SMALL_COUNT + 1) if not low <= c <= high]
        n = draw(st.sampled_from(bad))
        length = length or 25
    else:
        n = max(n, 1)
        length = draw(st.integers(0, 63).map(_skip(want_len)))
    body = draw(s.binary(n * length))
    header = Header(action=action, block_type=bt, block_count=n, block_length=length)
    note = f"{Action(action).name} with block type {bt:#04x}, N={n}, L={length} ({which} wrong)"
    return s.case("B5-shape", "B5", s.raw(header, body), note)


@st.composite
def _index(draw: st.DrawFn, s: Strategies) -> FuzzCase:
    """B3: a wrong first index, a gap or a repeat."""
    action = draw(s._block_action)
    bt, _low, high, length = _shape_of(action)
    n = min(draw(s._small), high)
    indexes = [(s.first + i) & 0xFF for i in range(n)]
    at = draw(st.integers(0, n - 1)) if n > 1 else 0
    indexes[at] = (indexes[at] + 1 + draw(st.integers(0, 254))) & 0xFF
    body = s.blocks(bt, n, draw(s.value_bytes(bt, n)), indexes)
    header = Header(action=action, block_type=bt, block_count=n, block_length=length)
    return s.case("B3-index", "B3", s.raw(header, body), f"{Action(action).name} ×{n} with block indexes {indexes}")


@st.composite
def _floats(draw: st.DrawFn, s: Strategies) -> FuzzCase:
    """B4: NaN (any payload), ±infinity (SHOULD be rejected) or legal edge values (-0, subnormals, max)."""
    action = draw(s._float_action)
    bt, _low, _high, length = _shape_of(action)
    n = draw(s._small)
    slots = (length - 1) // 4
    where = draw(st.integers(0, n * slots - 1))
    bits = draw(s._specials)
    if bits in NON_FINITE_BITS and bits & 0x7FFFFF > 1:  # a NaN: any payload will do
        bits = (bits & 0xFF800000) | draw(st.integers(0x400000, 0x7FFFFF))
    body = bytearray(s.blocks(bt, n, draw(s.value_bytes(bt, n))))
    offset = (where // slots) * length + 1 + (where % slots) * 4
    body[offset : offset + 4] = s._u32(bits)
    edge = bits in EDGE_FINITE_BITS
    header = Header(action=action, block_type=bt, block_count=n, block_length=length)
    note = f"{Action(action).name} ×{n} with {'legal edge' if edge else 'non-finite'} value {bits:08x} at value {where}"
    return s.case("B4-edge" if edge else "B4-non-finite", "B4", s.raw(header, bytes(body)), note)


@st.composite
def _truncated(draw: st.DrawFn, s: Strategies, spliced: bool) -> FuzzCase:
    """F5: a frame cut short, then the end of the stream (or, spliced, a whole frame right behind it)."""
    header, body = draw(s._request)
    data = s.raw(header, body)
    cut = draw(st.integers(1, len(data) - 1))
    name = Action(header.action).name
    if not spliced:
        return s.case("F5-truncated", "F5", data[:cut], f"{name} cut after {cut} of {len(data)} bytes", eof=True)
    nxt = s.raw(*draw(s._request))
    return s.case("F5-spliced", "F5", data[:cut] + nxt, f"{name} cut after {cut} of {len(data)} bytes, then a whole frame")


@st.composite
def _oversized(draw: st.DrawFn, s: Strategies) -> FuzzCase:
    """R5: a header announcing more than the largest legal frame (up to 255 × 65535 bytes)."""
    action = draw(s._action)
    bt, _low, _high, _length = _shape_of(action)
    n = MAX_BLOCK_COUNT - draw(st.integers(0, MAX_BLOCK_COUNT - 26))
    length = 65535 - draw(st.integers(0, 65535 - (6400 // n + 1)))
    junk = draw(st.binary(max_size=32))
    header = Header(action=action, block_type=bt, block_count=n, block_length=length)
    note = f"{Action(action).name} header announcing {n}×{length} = {n * length} bytes, then {len(junk)} bytes"
    return s.case("R5-oversized", "R5", s.raw(header, b"", b"") + junk, note)


_OPS = ("set", "flip", "insert", "delete")


@st.composite
def _mutated(draw: st.DrawFn, s: Strategies) -> FuzzCase:
    """Byte-level mutation of a valid request: one to three of set, flip, insert or delete a byte.

    The edits come from one ``binary`` draw, 4 bytes each (operation, position high and
    low byte, value): one choice however many edits, and it shrinks to "set byte 0 to 00"."""
    header, body = draw(s._request)
    data = bytearray(s.raw(header, body))
    ops = draw(s._edits)
    done = []
    for i in range(0, len(ops) - 3, 4):
        op, pos, value = _OPS[ops[i] % 4], (ops[i + 1] << 8) | ops[i + 2], ops[i + 3]
        at = pos % (len(data) + 1 if op == "insert" else max(1, len(data)))
        if op == "set" and data:
            data[at] = value
        elif op == "flip" and data:
            data[at] ^= 1 << (value % 8)
        elif op == "insert":
            data.insert(at, value)
        elif op == "delete" and len(data) > 1:
            del data[at]
        done.append(f"{op}@{at}" + (f"={value:02x}" if op in ("set", "insert") else ""))
    recount = _recount(s, header, body, bytes(data))
    if recount is not None:
        count = getattr(peek_header(recount), "block_count", 0)
        return s.case("mutation", "", recount, f"a valid request mutated: {', '.join(done)}; "
                      f"its blocks rebuilt for count {count} (a well-formed frame of that count)")
    return s.case("mutation", "", bytes(data), "a valid request mutated: " + ", ".join(done))


def _recount(s: Strategies, header: Header, body: bytes, data: bytes) -> bytes | None:
    """When the edits changed only the block count of a block request: a well-formed frame of the new
    count (its blocks indexed and filled like the first ones), not a header whose body is zero filler."""
    new, old = peek_header(data), peek_header(s.raw(header, body))
    if new is None or old is None or new.block_count in (old.block_count, 0) \
            or dataclasses.replace(new, block_count=old.block_count) != old or header.action not in BLOCK_ACTIONS:
        return None
    per, count = header.block_length - 1, new.block_count
    values = b"".join(body[i * (per + 1) + 1 : (i + 1) * (per + 1)] for i in range(min(header.block_count, SMALL_COUNT)))
    return s.raw(dataclasses.replace(header, block_count=count), s.blocks(header.block_type, count, values))


@st.composite
def _datagram(draw: st.DrawFn, s: Strategies) -> FuzzCase:
    """One UDP datagram: valid with its CRC, a wrong CRC (F7), cut or padded (F5/R7), or a bad index with a good CRC."""
    header, body = draw(s._request)
    U = Transport.UDP
    frame = s.raw(header, body, transport=U)
    name = Action(header.action).name
    which = draw(st.sampled_from(("valid", "crc", "cut", "padded", "index")))
    if which == "crc":
        bad = draw(s.binary(2))
        bad = bad if bad != frame[-2:] else bytes([bad[0] ^ 1, bad[1]])
        return s.case("F7-crc", "F7", frame[:-2] + bad, f"{name} datagram with check {bad.hex(' ')}", U)
    if which == "cut":
        cut = draw(st.integers(0, len(frame) - 1))
        return s.case("F7-cut", "F5", frame[:cut], f"{name} datagram cut to {cut} bytes", U)
    if which == "padded":
        extra = draw(st.binary(min_size=1, max_size=8))
        return s.case("F7-padded", "F5", frame + extra, f"{name} datagram with {len(extra)} extra bytes", U)
    if which == "index" and header.block_count:
        body = bytes([(body[0] + 1) & 0xFF]) + body[1:]
        return s.case("F7-index", "B3", s.raw(header, body, transport=U), f"{name} datagram (good CRC), first index wrong", U)
    return s.case("F7-valid", "", frame, f"{name} datagram with its CRC", U)


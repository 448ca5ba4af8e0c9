"""How much of the input space a campaign reached: block counts, header field values, float classes, sizes.

Each *space* is a finite set of points named in advance, so a campaign reports a
fraction, not just a count:

* **counts**: a well-formed pose, register-pose or tolerance request of every block
  count 1-255 (B1, B2: 3 × 255 points; only requests the oracle calls well-formed count);
* **fields**: each header field at each of its boundary values (:data:`EDGES_U8`,
  :data:`EDGES_U16`: 0, 1, every power of two and its neighbours, the largest value)
  plus the values the protocol defines for it, read from the first header of a case;
* **values**: the IEEE-754 classes of float32 (:func:`float_class`: ±0, subnormals,
  normals, huge magnitudes, the largest finite, ±infinity, quiet, signalling and
  negative NaNs) found in a pose or tolerance body;
* **sizes**: the length of what was written, in power-of-two buckets up to 128 KiB,
  with the largest legal frame (:data:`MAX_FRAME_LEN`) and one byte more as points of their own.

:class:`Coverage` observes every case a campaign sends; ``to_dict()`` goes into
``fuzz-summary.json``. The deterministic schedule (:mod:`.schedule`) draws from the
same tables, so every point it can reach is reached early.
"""

from __future__ import annotations

from typing import Any

from ..protocol import HEADER_LEN, MAX_FRAME_LEN, Action, BlockType, Profile, peek_header
from ..protocol.constants import HEADER_FIELDS, START_WORD
from .strategies import BLOCK_ACTIONS, FuzzCase


def _edges(bits: int) -> tuple[int, ...]:
    top = (1 << bits) - 1
    out = {0, 1, top, top - 1}
    for k in range(1, bits):
        p = 1 << k
        out |= {p - 1, p, p + 1}
    return tuple(sorted(v for v in out if 0 <= v <= top))


#: Boundary values of a one-byte and a two-byte field.
EDGES_U8 = _edges(8)
EDGES_U16 = _edges(16)
#: Header fields: (name, offset, width, values the protocol defines).
FIELDS: tuple[tuple[str, int, int, tuple[int, ...]], ...] = tuple((name, *HEADER_FIELDS[name], defined) for name, defined in (
    ("start_word", (START_WORD, 0xFEFF, 0xFFFE, 0x00FE, 0xFE00)),
    ("version", (0x0001, 0x0100, 0x0002)),
    ("transfer_type", (0x01, 0x10, 0x11)),
    ("action", tuple(int(a) for a in Action)),
    ("block_type", tuple(int(b) for b in BlockType)),
    ("block_count", ()),
    ("block_length", (5, 24, 25, 26)),
    ("error_code", (0x0001, 0x0002, 0x03E9, 0x03EA, 0x0194, 0x0199)),
))
#: The float32 classes (``float_class``), most ordinary first.
VALUE_CLASSES = ("zero", "-zero", "normal", "-normal", "subnormal", "-subnormal", "min-normal", "huge", "-huge",
                 "max-finite", "-max-finite", "inf", "-inf", "qnan", "snan", "-nan")
#: Size buckets: [2^k, 2^(k+1)) for k = 0..16, and the largest legal frame and one byte more.
SIZE_POINTS = tuple(f"<{1 << (k + 1)}" for k in range(17)) + ("max-frame", "max-frame+1")


def field_space() -> dict[str, tuple[int, ...]]:
    """Field name -> the values the space holds for it."""
    return {name: tuple(sorted(set(EDGES_U8 if width == 1 else EDGES_U16) | set(defined)))
            for name, _off, width, defined in FIELDS}


def float_class(bits: int) -> str:
    """The IEEE-754 binary32 class of a 32-bit pattern (one of :data:`VALUE_CLASSES`)."""
    sign = "-" if bits & 0x80000000 else ""
    exp, frac = (bits >> 23) & 0xFF, bits & 0x7FFFFF
    if exp == 0xFF:
        if not frac:
            return sign + "inf"
        if sign:
            return "-nan"
        return "qnan" if frac & 0x400000 else "snan"
    if exp == 0:
        return sign + ("zero" if not frac else "subnormal")
    if exp == 0xFE and frac == 0x7FFFFF:
        return sign + "max-finite"
    if exp == 1 and frac == 0:
        return "min-normal"
    if exp >= 0xE2:  # 2^99 ≈ 6.3e29 (1e30 and up)
        return sign + "huge"
    return sign + "normal"


def size_point(n: int) -> str:
    if n == MAX_FRAME_LEN:
        return "max-frame"
    if n == MAX_FRAME_LEN + 1:
        return "max-frame+1"
    return f"<{1 << min(17, max(1, n.bit_length()))}"


class Coverage:
    """The points of each space a campaign reached (see the module docstring)."""

    def __init__(self, profile: Profile) -> None:
        self.order = profile.byte_order
        self.forder = profile.float_byte_order
        self.space = field_space()
        self.counts: dict[int, set[int]] = {int(a): set() for a in BLOCK_ACTIONS}
        self.fields: dict[str, set[int]] = {name: set() for name in self.space}
        self.values: set[str] = set()
        self.sizes: set[str] = set()

    def observe(self, case: FuzzCase) -> None:
        data = case.data
        self.sizes.add(size_point(len(case.wire)))
        head = peek_header(data, 0, self.order)
        if head is None:
            return
        for name, *_ in FIELDS:
            self.fields[name].add(getattr(head, name))
        action, n = head.action, head.block_count
        if case.valid and action in self.counts and len(case.expects) == 1:
            self.counts[action].add(n)
        if head.block_type in (BlockType.POSE, BlockType.TOLERANCE):
            self._floats(data, head.block_length, n)

    def _floats(self, data: bytes, length: int, n: int) -> None:
        if length not in (5, 25):
            return
        end = min(len(data), HEADER_LEN + min(n, 16) * length)
        for start in range(HEADER_LEN, end - length + 1, length):
            for at in range(start + 1, start + length, 4):
                self.values.add(float_class(int.from_bytes(data[at : at + 4], self.forder)))

    # -- figures -----------------------------------------------------------------------------
    def fractions(self) -> dict[str, float]:
        counts = sum(len(v & set(range(1, 256))) for v in self.counts.values()) / (255 * len(self.counts))
        reached = sum(len(self.fields[k] & set(v)) for k, v in self.space.items())
        fields = reached / sum(len(v) for v in self.space.values())
        values = len(self.values & set(VALUE_CLASSES)) / len(VALUE_CLASSES)
        sizes = len(self.sizes & set(SIZE_POINTS)) / len(SIZE_POINTS)
        return {"counts": round(counts, 4), "fields": round(fields, 4), "values": round(values, 4),
                "sizes": round(sizes, 4)}

    def to_dict(self) -> dict[str, Any]:
        def missing(have: set[Any], space: tuple[Any, ...]) -> list[Any]:
            return [v for v in space if v not in have][:12]

        return {
            "fraction": self.fractions(),
            "counts": {Action(a).name: {"reached": len(v & set(range(1, 256))), "of": 255,
                                        "missing": missing(v, tuple(range(1, 256)))}
                       for a, v in self.counts.items()},
            "fields": {k: {"reached": len(self.fields[k] & set(v)), "of": len(v), "missing": missing(self.fields[k], v)}
                       for k, v in self.space.items()},
            "values": {"reached": sorted(self.values & set(VALUE_CLASSES)),
                       "missing": missing(self.values, VALUE_CLASSES)},
            "sizes": {"reached": len(self.sizes & set(SIZE_POINTS)), "of": len(SIZE_POINTS),
                      "missing": missing(self.sizes, SIZE_POINTS)},
        }


__all__ = ["EDGES_U8", "EDGES_U16", "FIELDS", "SIZE_POINTS", "VALUE_CLASSES", "Coverage", "field_space", "float_class",
           "size_point"]

"""Answers built wrongly, field by field (pure): which one field of an answer differs from every allowed answer.

An answer to a valid request is compared, field by field, with the answers PROTOCOL.md allows for its action
(:data:`~conformance.protocol.ANSWER_SHAPE`: A2 no blocks for 00-25, E2/E3 one type-03 block for 26/27). The
first field that differs is the failure-inducing difference, named in the protocol's words:

* ``echo-blocks`` — the request's blocks copied back (block type, count, length and data equal the request's),
  where A2 asks for an answer with no blocks;
* ``blocks-attached`` — blocks attached to an answer that carries none;
* ``block-type`` / ``block-count`` / ``block-length`` — the answer's block header differs from E2/E3's.

:func:`swap_story` decides between two stories for an error code no action allows (``0200`` to a CycleOff,
``0110`` to a bad pose): a box that refuses with that code, or one that writes every error code little-endian.
Byte order is confirmed only when swapping the two bytes makes *every* observed answer legal and at least one
answer illegal as sent; one answer legal as sent but not swapped (a ``1001`` written big-endian) rules it out.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import Literal

from ..i18n import gettext
from ..protocol import ANSWER_SHAPE, BLOCK_LEN, Action
from ..protocol.answers import CONFLICT, SENDABLE_RESULTS
from ..protocol.constants import HEADER_LEN, START_WORD, VALUE_BLOCK_LEN, VERSION, BlockType, TransferType
from . import titles

Order = Literal["big", "little"]


@dataclass(frozen=True)
class ShapeDiff:
    """The one field in which an answer to a valid ``action`` request differs from the allowed answers."""

    action: int
    field: str  # "transfer-type" | "version" | "echo-blocks" | "blocks-attached" | "block-type" | "block-count" |
    # "block-length" | "value"
    got: int
    want: int
    header: bytes = b""  # the answer's block type, count and length bytes (6..9)


def _u16(raw: bytes, at: int, order: Order = "big") -> int:
    return int.from_bytes(raw[at:at + 2], order)


def shape_diff(action: int, request: bytes, answer: bytes, order: Order = "big") -> ShapeDiff | None:
    """The first field of ``answer`` (to the valid ``request``) outside every allowed answer; None when its
    transfer type, version, block header (and a 26/27 answer's block value) are allowed (other defects are other
    families' business). ``order``: the profile's byte order of the header and the int32 (F4, E1)."""
    if len(answer) < HEADER_LEN or len(request) < HEADER_LEN:
        return None
    if answer[:2] != START_WORD.to_bytes(2, "big") or answer[5] != action:  # not recognisably this request's answer (F1, A2: theirs)
        return None
    try:
        shape = ANSWER_SHAPE[Action(action)]
    except ValueError:
        return None
    if answer[4] != TransferType.BOX_TO_ROBOT:
        return ShapeDiff(action, "transfer-type", answer[4], int(TransferType.BOX_TO_ROBOT), bytes(answer[4:5]))
    if _u16(answer, 2, order) != VERSION:
        return ShapeDiff(action, "version", _u16(answer, 2), VERSION, bytes(answer[2:4]))
    bt, count, length = answer[6], answer[7], _u16(answer, 8, order)
    head = bytes(answer[6:10])
    if shape.block_type is BlockType.EMPTY:
        if count == 0:  # no blocks, yet a block type or length other than 00 / 0 in the header
            return (ShapeDiff(action, "block-type", bt, 0, head) if bt else
                    ShapeDiff(action, "block-length", length, 0, head) if length else None)
        body = request[HEADER_LEN:HEADER_LEN + request[7] * _u16(request, 8, order)]
        same = head == bytes(request[6:10]) and answer[HEADER_LEN:HEADER_LEN + len(body)] == body
        return ShapeDiff(action, "echo-blocks" if same else "blocks-attached", count, 0, head)
    want_len = BLOCK_LEN[shape.block_type]
    if bt != shape.block_type:
        return ShapeDiff(action, "block-type", bt, int(shape.block_type), head)
    if not shape.low <= count <= shape.high:
        return ShapeDiff(action, "block-count", count, shape.high, head)
    if length != want_len:
        return ShapeDiff(action, "block-length", length, want_len, head)
    return _value_diff(action, request, answer, order)


def _value_diff(action: int, request: bytes, answer: bytes, order: Order) -> ShapeDiff | None:
    """E2: a ProgIdx answer carries the index sent or 409; E3: a result answer a ResultCode a box sends."""
    if len(answer) < HEADER_LEN + VALUE_BLOCK_LEN:
        return None
    value = int.from_bytes(answer[HEADER_LEN + 1:HEADER_LEN + 5], order, signed=True)
    if action == Action.PROG_IDX and len(request) >= HEADER_LEN + VALUE_BLOCK_LEN:
        sent = int.from_bytes(request[HEADER_LEN + 1:HEADER_LEN + 5], order, signed=True)
        if value not in (sent, CONFLICT):
            return ShapeDiff(action, "value", value, sent, bytes(answer[HEADER_LEN + 1:HEADER_LEN + 5]))
    if action == Action.VISION_RESULT and value not in SENDABLE_RESULTS:
        return ShapeDiff(action, "value", value, 1, bytes(answer[HEADER_LEN + 1:HEADER_LEN + 5]))
    return None


def names(actions: Iterable[int]) -> str:
    """Actions as a title lists them: pose (23), register pose (24) and tolerance (25)."""
    named = [titles.name(a) for a in sorted(set(actions))]
    return named[0] if len(named) == 1 else gettext("{some} and {last}").format(some=", ".join(named[:-1]),
                                                                              last=named[-1])


def shape_title(diffs: Sequence[ShapeDiff]) -> str:
    """One line for the answers of one defect (``diffs`` share their field), in the protocol's words."""
    first = diffs[0]
    actions = names(d.action for d in diffs)
    head = first.header.hex(" ")
    if first.field == "echo-blocks":
        return gettext("Answers {actions} with the request's blocks copied back (block type, count, length and data "
                       "echoed: {head} …) instead of an answer with no blocks: A2 asks for block type 00, count 0, "
                       "length 0 — answer without blocks").format(actions=actions, head=head)
    if first.field == "blocks-attached":
        return gettext("Answers {actions} with blocks attached (block type, count, length {head}) instead of an "
                       "answer with no blocks: A2 asks for block type 00, count 0, length 0 — answer without "
                       "blocks").format(actions=actions, head=head)
    if first.field == "transfer-type":
        return gettext("Answers {actions} with transfer type {got:02X} where F3 asks for 10 (box to robot) in every "
                       "answer — write 10 in byte 4 of the answer").format(actions=actions, got=first.got)
    if first.field == "version":
        return gettext("Answers {actions} with version {head} where F2 asks for 00 01 in every frame — write the "
                       "version 00 01 (big-endian) in the answer").format(actions=actions, head=head)
    clause = ANSWER_SHAPE[Action(first.action)].clause
    if first.field == "value":
        if first.action == Action.PROG_IDX:
            return gettext("Answers ProgIdx (26) with the value {got} in its type-03 block where E2 asks for the "
                           "program index sent ({want}) or 409 — echo the index").format(got=first.got, want=first.want)
        return gettext("Answers the result request (27) with the value {got} in its type-03 block, which is not a "
                       "ResultCode a box sends (E3: 1, 2, 10, 20, 202, 400, 409) — answer with a ResultCode").format(
            got=first.got)
    if first.field == "block-type" and first.want == 0:
        return gettext("Answers {actions} with block type {got:02X} (and no blocks) where A2 asks for block type 00 in "
                       "an answer without blocks — write block type 00").format(actions=actions, got=first.got)
    if first.field == "block-type":
        return gettext("Answers {actions} with block type {got:02X} where {clause} asks for block type {want:02X} "
                       "(the answer's block is of the wrong type) — answer with a type-{want:02X} block").format(
            actions=actions, got=first.got, want=first.want, clause=clause)
    if first.field == "block-count":
        return gettext("Answers {actions} with block count {got} where {clause} asks for {want} block — answer "
                       "with {want} block").format(actions=actions, got=first.got, want=first.want, clause=clause)
    return gettext("Answers {actions} with block length {got} where {clause} asks for block length {want} — "
                   "answer with {want}-byte blocks").format(actions=actions, got=first.got, want=first.want,
                                                            clause=clause)


def grouped(diffs: Sequence[ShapeDiff]) -> list[list[ShapeDiff]]:
    """The diffs by field (one defect each), the field seen for most actions first."""
    by: dict[tuple[str, int, int], list[ShapeDiff]] = {}
    for d in diffs:
        key = (d.field, d.got if d.field.startswith("block-") or d.field in ("transfer-type", "version") else 0, d.want)
        by.setdefault(key, []).append(d)
    return sorted(by.values(), key=lambda g: -len(g))


# -- error code byte order ------------------------------------------------------------------------------------
def swapped(code: int) -> int:
    return ((code & 0xFF) << 8) | (code >> 8)


@dataclass(frozen=True)
class Observed:
    """One answer's error code, and the codes its request allows (a valid request's, or a parse error's
    named code)."""

    action: int
    code: int
    legal: frozenset[int]


def swap_story(seen: Sequence[Observed]) -> tuple[bool, str]:
    """(confirmed, why): the error codes written little-endian, when swapping makes every answer legal."""
    wrong = [o for o in seen if o.code not in o.legal]
    if not wrong:
        return False, "every error code is legal as sent"
    fixed = [o for o in wrong if swapped(o.code) in o.legal]
    if len(fixed) < len(wrong):
        o = next(o for o in wrong if swapped(o.code) not in o.legal)
        return False, f"{o.code:04X} to {titles.name(o.action)} is not legal swapped either"
    spoilt = [o for o in seen if o.code in o.legal and swapped(o.code) not in o.legal]
    if spoilt:
        o = spoilt[0]
        return False, f"{o.code:04X} to {titles.name(o.action)} is written big-endian (swapped it would be wrong)"
    if len({o.code for o in fixed}) < 2:
        return False, "one code alone: refused with that code, or written little-endian (not told apart)"
    return True, "; ".join(f"{o.code:04X} to {titles.name(o.action)} is {swapped(o.code):04X} swapped" for o in fixed)


def swap_title(seen: Sequence[Observed], order: Order = "big") -> str:
    shown = list(dict.fromkeys(swapped(o.code) for o in seen if o.code not in o.legal))[:2]
    examples = ", ".join(gettext("{code:04X} goes out as {low:02X} {high:02X}").format(code=c, low=c & 0xFF,
                                                                                       high=c >> 8) for c in shown)
    if order != "big":  # the profile's header byte order is little-endian: the box writes the other one
        return gettext("Writes the error code of its answers in the wrong byte order (big-endian where the profile "
                       "reads little-endian): {examples} — write the error code in the profile's byte order").format(
            examples=examples)
    return gettext("Writes the error code of its answers in the wrong byte order (little-endian): {examples}: F4 asks "
                   "for big-endian fields — write bytes 10-11 most significant first").format(examples=examples)


#: every error code A3 names (S2, A3): a code outside them that is one of them swapped hints at the byte order
NAMED_CODES = frozenset({0x0001, 0x0002, 0x1001, 0x1002})


def swap_hints(received: Iterable[bytes], order: Order = "big") -> set[int]:
    """The error codes of the answers quoted in ``received`` (each headed FE FE .. 10) that no action allows
    but that swapped are a code A3 names: worth the byte-order experiment."""
    out: set[int] = set()
    for raw in received:
        at = raw.find(b"\xfe\xfe")
        while 0 <= at <= len(raw) - HEADER_LEN:
            if raw[at + 4] == TransferType.BOX_TO_ROBOT:
                code = int.from_bytes(raw[at + 10:at + 12], order)
                if code not in NAMED_CODES and swapped(code) in NAMED_CODES:
                    out.add(code)
            at = raw.find(b"\xfe\xfe", at + 2)
    return out

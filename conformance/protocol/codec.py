"""Encode frames and parse exactly one frame from bytes (sans-I/O): the compiled :class:`Codec`.

:meth:`Codec.parse` (``parse_frame`` in api.py) checks a complete frame against F, B,
A2/A4/A5 and E1–E3 and raises a typed :class:`~.errors.ProtocolError` naming the first
clause it breaks. The order (the one vectors/README.md fixes) is: fewer than 12 bytes F5;
the header (F1 start word, F2 version, F3 transfer type, A5 action, then the action's
block type, length and count: B5/B1/B2/E1/E2/E3/A2); total length F5; F6 TCP check (per
the profile's policy) or F7 UDP CRC; B3 indexes and B4 floats block by block; answer
content (A4 action 00 answered 0000, E3 result code never 0 or 404).
"""

from __future__ import annotations

import struct
from collections.abc import Iterable, Sequence
from math import isfinite
from typing import cast

from .constants import (
    BLOCK_CLAUSE,
    BLOCK_LEN,
    CHECK_LEN,
    HEADER_LEN,
    MAX_BLOCK_COUNT,
    POSE_BLOCK_LEN,
    SHAPES,
    START_WORD,
    TOLERANCE_BLOCK_LEN,
    VERSION,
    Action,
    BlockType,
    ResultCode,
    Shape,
    TransferType,
    Transport,
)
from .errors import (
    AnswerError,
    BlockIndexError,
    CheckError,
    DirectionError,
    FloatError,
    LengthError,
    ProtocolError,
    ShapeError,
    StartWordError,
    UnknownActionError,
    VersionError,
)
from .frames import (
    Block,
    Frame,
    Header,
    PoseBlock,
    ToleranceBlock,
    ValueBlock,
    new_frame,
    new_pose_block,
    new_pose_blocks,
    pose_blocks,
    tolerance_blocks,
    value_blocks,
)
from .profile import DEFAULT_PROFILE, Profile, TcpCheckPolicy, crc_function

_ENDIAN = {"big": ">", "little": "<"}
_TRANSFER = {t.value: t for t in TransferType}
_ACTION = {a.value: a for a in Action}
_BLOCK_TYPE = {b.value: b for b in BlockType}
_ZERO_CHECK = b"\x00\x00"
_TCP = Transport.TCP
#: (transfer type << 8 | action) -> (TransferType, Action, block type, L, fewest, most):
#: the shape table of constants.SHAPES flattened to ints for the fast path.
_RULES = {
    (tt << 8) | act: (tt, act, shape.block_type.value, BLOCK_LEN[shape.block_type], shape.low, shape.high)
    for tt, by_action in SHAPES.items()
    for act, shape in by_action.items()
    # answers whose content is checked (A4, E3) take the reference path
    if not (tt is TransferType.BOX_TO_ROBOT and act in (Action.NONE, Action.VISION_RESULT))
}


class Codec:
    """Encoder and single-frame parser compiled for one profile (get it with :func:`codec_for`)."""

    def __init__(self, profile: Profile) -> None:
        self.profile = profile
        e, f = _ENDIAN[profile.byte_order], _ENDIAN[profile.float_byte_order]
        self.header = struct.Struct(e + "HHBBBBHH")
        self.pose = struct.Struct(f + "B6f")
        self.tolerance = struct.Struct(f + "Bf")
        self.value = struct.Struct(f + "Bi")
        self._unpack_header = self.header.unpack_from
        self._u16 = struct.Struct(e + "H").unpack_from
        #: a 16-bit header field's two bytes in this byte order
        self.pack_u16 = struct.Struct(e + "H").pack
        #: the first four bytes of every frame in this byte order: start word and version (F1, F2)
        self.start = struct.pack(e + "HH", START_WORD, VERSION)
        self._unpack_pose = self.pose.unpack_from
        self._pose_runs: dict[int, struct.Struct] = {}
        self._float_order = f
        # the stream's frame (one pose, 39 bytes) in one unpack, when one byte order serves all
        self._unpack_one_pose = (
            struct.Struct(e + "HHBBBBHHB6fH").unpack if profile.byte_order == profile.float_byte_order else None
        )
        self._crc = crc_function(profile.crc)
        self._crc_pack = struct.Struct(_ENDIAN[profile.crc_byte_order] + "H").pack
        self._first = profile.first_index
        self._strict = profile.strict
        self._tcp_check = profile.tcp_check

    # -- blocks by position: the profile's first index is applied here, not by the caller (B3) --
    def block_index(self, position: int) -> int:
        """B3: the index of the block at ``position`` (0: the first block) under this profile."""
        return self._first + position

    def pose_blocks(self, poses: Iterable[Sequence[float]]) -> tuple[PoseBlock, ...]:
        return pose_blocks(poses, self._first)

    def tolerance_blocks(self, values: Iterable[float]) -> tuple[ToleranceBlock, ...]:
        return tolerance_blocks(values, self._first)

    def value_blocks(self, values: Iterable[int]) -> tuple[ValueBlock, ...]:
        return value_blocks(values, self._first)

    # -- encoding --------------------------------------------------------------------
    def check_bytes(self, body: bytes) -> bytes:
        return self._crc_pack(self._crc(body))

    def encode_header(self, header: Header) -> bytes:
        try:
            return self.header.pack(
                header.start_word, header.version, header.transfer_type, header.action,
                header.block_type, header.block_count, header.block_length, header.error_code,
            )
        except struct.error as exc:
            raise ValueError(f"header field out of range: {exc}") from None

    def encode_block(self, block: Block) -> bytes:
        try:
            if type(block) is PoseBlock:
                if len(block.pose) != 6:
                    raise ValueError(f"a pose has 6 values, not {len(block.pose)}")
                return self.pose.pack(block.index, *block.pose)
            if type(block) is ToleranceBlock:
                return self.tolerance.pack(block.index, block.tolerance)
            if type(block) is ValueBlock:
                return self.value.pack(block.index, block.value)
        except (struct.error, OverflowError, TypeError) as exc:
            raise ValueError(f"block value out of range in {block!r}: {exc}") from None
        raise TypeError(f"not a block: {block!r}")

    def encode_body(self, frame: Frame) -> bytes:
        blocks = frame.blocks
        count = len(blocks)
        if not count:
            try:
                return self.header.pack(START_WORD, VERSION, frame.transfer_type, frame.action, 0, 0, 0, frame.error_code)
            except struct.error as exc:
                raise ValueError(f"header field out of range: {exc}") from None
        kind = type(blocks[0])
        if count > MAX_BLOCK_COUNT:
            raise ValueError(f"{count} blocks; a frame carries at most {MAX_BLOCK_COUNT}")
        if count > 1 and any(type(b) is not kind for b in blocks):
            raise ValueError("a frame's blocks must all be of one type")
        block_type = kind.block_type
        try:
            head = self.header.pack(
                START_WORD, VERSION, frame.transfer_type, frame.action, block_type,
                count, BLOCK_LEN[block_type], frame.error_code,
            )
            if kind is PoseBlock:
                pack = self.pose.pack
                poses = cast("tuple[PoseBlock, ...]", blocks)  # all of one type, checked above
                return head + b"".join([pack(b.index, *b.pose) for b in poses])
        except (struct.error, TypeError):
            pass  # fall through to the slow path for a precise message
        else:
            if kind is not PoseBlock:
                return head + b"".join([self.encode_block(b) for b in blocks])
        self.encode_header(frame.header)
        for b in blocks:
            self.encode_block(b)
        raise ValueError(f"cannot encode {frame!r}")  # pragma: no cover

    def encode(self, frame: Frame, transport: Transport = Transport.TCP) -> bytes:
        body = self.encode_body(frame)
        if transport is Transport.TCP or transport == "tcp":
            return body + _ZERO_CHECK
        return body + self.check_bytes(body)

    def encode_raw(
        self, header: Header, body: bytes = b"", check: bytes | None = None, transport: Transport = Transport.TCP
    ) -> bytes:
        data = self.encode_header(header) + bytes(body)
        if check is None:
            check = _ZERO_CHECK if transport == "tcp" else self.check_bytes(data)
        return data + bytes(check)

    # -- reading fields ----------------------------------------------------------------
    def u16(self, data: bytes, at: int) -> int:
        """A 16-bit header field at ``at`` in the profile's byte order (version, L, error code)."""
        return int(self._u16(data, at)[0])

    def frame_length(self, data: bytes, at: int = 0) -> int:
        """The length of the whole frame a header at ``at`` announces: header + N × L + check
        (``data`` holds at least the header's first 10 bytes there)."""
        return HEADER_LEN + data[at + 7] * int(self._u16(data, at + 8)[0]) + CHECK_LEN

    # -- parsing ---------------------------------------------------------------------
    def parse_header(self, data: bytes) -> Header:
        return Header(*self.header.unpack_from(data))

    def _fail(self, cls: type[ProtocolError], msg: str, data: bytes, offset: int, clause: str | None = None) -> ProtocolError:
        header = self.parse_header(data) if len(data) >= HEADER_LEN else None
        return cls(msg, offset=offset, raw=bytes(data), header=header, clause=clause)

    def parse(self, data: bytes, transport: Transport = Transport.TCP, expect: TransferType | None = None) -> Frame:
        """Parse exactly one complete frame; raise a ProtocolError naming the clause.

        The fast path below only *returns* for a TCP frame that passes every header
        check; anything else goes to :meth:`parse_checked`, which defines the result.
        """
        size = len(data)
        if size == 39 and transport is _TCP and self._unpack_one_pose is not None:
            start, version, tt, act, bt, count, blen, error_code, index, x, y, z, w, p, r, check = (
                self._unpack_one_pose(data)
            )
            rule = _RULES.get((tt << 8) | act)
            if (
                rule is not None
                and start == 0xFEFE
                and version == 1
                and bt == 1
                and count == 1
                and blen == 25
                and not check
                and index == self._first
                and rule[2] == 1
                and (expect is None or rule[0] is expect)
                and (not self._strict or isfinite(x + y + z + w + p + r))
            ):
                return new_frame(rule[0], rule[1], (new_pose_block(index, (x, y, z, w, p, r)),), error_code, 0)
        if size >= 14 and transport is _TCP:
            start, version, tt, act, bt, count, blen, error_code = self._unpack_header(data)
            rule = _RULES.get((tt << 8) | act)
            end = 12 + count * blen
            if (
                rule is not None
                and start == 0xFEFE
                and version == 1
                and size == end + 2
                and bt == rule[2]
                and blen == rule[3]
                and rule[4] <= count <= rule[5]
                and (expect is None or rule[0] is expect)
                and not data[end]
                and not data[end + 1]
            ):
                if not count:
                    blocks: tuple[Block, ...] = ()
                elif count == 1 and bt == 1 and data[12] == self._first:
                    index, x, y, z, w, p, r = self._unpack_pose(data, 12)
                    if self._strict and not isfinite(x + y + z + w + p + r):
                        raise self._fail(FloatError, "block 0: non-finite pose value", data, HEADER_LEN + 1)
                    blocks = (new_pose_block(index, (x, y, z, w, p, r)),)
                else:
                    blocks = self._parse_blocks(data, rule[2], count)
                return new_frame(rule[0], rule[1], blocks, error_code, 0)
        return self.parse_checked(data, transport, expect)

    def parse_checked(
        self, data: bytes, transport: Transport = Transport.TCP, expect: TransferType | None = None
    ) -> Frame:
        """The reference parser: every check in the order of the module docstring."""
        size = len(data)
        fail = self._fail
        if size < HEADER_LEN:
            raise fail(LengthError, f"{size} bytes, shorter than the 12-byte header", data, size)
        ttype, action, btype = self.check_header(data, expect)
        _start, _version, _tt, _act, _bt, count, blen, error_code = self.header.unpack_from(data)
        end = HEADER_LEN + count * blen
        if size != end + CHECK_LEN:
            raise fail(LengthError, _length_text(size, count, blen), data, min(size, end + CHECK_LEN))
        check = (data[end] << 8) | data[end + 1]
        if transport is Transport.TCP or transport == "tcp":
            policy = self._tcp_check
            if check and (
                policy is TcpCheckPolicy.ZERO
                or (policy is TcpCheckPolicy.ZERO_OR_CRC and data[end:] != self.check_bytes(bytes(data[:end])))
            ):
                raise fail(CheckError, f"TCP check 0x{check:04X}, expected 00 00", data, end, "F6")
        else:
            want = self.check_bytes(bytes(data[:end]))
            if data[end:] != want:
                raise fail(CheckError, self._crc_text(data[end:], want), data, end, "F7")
        blocks = self._parse_blocks(data, btype, count) if count else ()
        if ttype is TransferType.BOX_TO_ROBOT:
            self._check_answer_content(data, action, error_code, blocks)
        return new_frame(ttype, action, blocks, error_code, check)

    def datagram_damage(self, data: bytes) -> tuple[str, str] | None:
        """R7: why a UDP datagram is not one intact frame (its clause and what is wrong), or None,
        whatever else is wrong with it (:meth:`parse` names the header's errors first, but a
        receiver may check a datagram's length and CRC before it reads the header)."""
        size = len(data)
        if size < HEADER_LEN + CHECK_LEN:
            return "F5", f"{size} bytes, shorter than the 14 bytes of the smallest frame"
        count, blen = self.header.unpack_from(data)[5:7]
        end = HEADER_LEN + count * blen
        if size != end + CHECK_LEN:
            return "F5", _length_text(size, count, blen)
        want = self.check_bytes(bytes(data[:end]))
        if data[end:] != want:
            return "F7", self._crc_text(data[end:], want)
        return None

    def _crc_text(self, got: bytes, want: bytes) -> str:
        return f"check {bytes(got).hex(' ')}, expected {self.profile.crc} CRC {want.hex(' ')}"

    def check_header(self, data: bytes, expect: TransferType | None = None) -> tuple[TransferType, Action, BlockType]:
        """F1, F2, F3, A5 and the action's shape (B5/B1/B2/E1–E3/A2) of 12 header bytes."""
        fail = self._fail
        start, version, tt, act, bt, count, blen, _error = self.header.unpack_from(data)
        if start != START_WORD:
            raise fail(StartWordError, f"start word {bytes(data[:2]).hex(' ')}, expected fe fe", data, 0)
        if version != VERSION:
            raise fail(VersionError, f"version 0x{version:04X}, expected 0x0001", data, 2)
        ttype = _TRANSFER.get(tt)
        if ttype is None or (expect is not None and ttype is not expect):
            want_tt = f"0x{expect.value:02X}" if expect is not None else "0x01 or 0x10"
            raise fail(DirectionError, f"transfer type 0x{tt:02X}, expected {want_tt}", data, 4)
        action = _ACTION.get(act)
        if action is None:
            raise fail(UnknownActionError, f"unknown action 0x{act:02X}", data, 5)
        shape = SHAPES[ttype][action]
        btype = _BLOCK_TYPE.get(bt)
        if btype is not shape.block_type or blen != BLOCK_LEN[btype] or not shape.low <= count <= shape.high:
            raise self._shape_error(data, ttype, action, shape, btype, bt, blen, count)
        return ttype, action, btype

    def _check_answer_content(self, data: bytes, action: Action, error_code: int, blocks: tuple[Block, ...]) -> None:
        """A4: action 00 is answered 0000. E3: 0 and 404 are the robot's own values, never sent."""
        if action is Action.NONE and error_code:
            raise self._fail(AnswerError, f"NONE answered with error 0x{error_code:04X}, expected 0x0000", data, 10, "A4")
        block = blocks[0] if blocks else None
        if action is Action.VISION_RESULT and isinstance(block, ValueBlock):  # its shape: one type-03 block
            value = block.value
            if value in (ResultCode.EMPTY, ResultCode.NO_ANSWER):
                raise self._fail(
                    AnswerError, f"result code {value} is the robot's own value, never sent by a box", data, 13, "E3"
                )

    def _shape_error(
        self, data: bytes, ttype: TransferType, action: Action, shape: Shape,
        btype: BlockType | None, bt: int, blen: int, count: int,
    ) -> ProtocolError:
        role = "request" if ttype is TransferType.ROBOT_TO_BOX else "answer"
        if btype is not shape.block_type:
            return self._fail(
                ShapeError, f"{action.name} {role} needs block type 0x{shape.block_type:02X}, got 0x{bt:02X}",
                data, 6, shape.clause,
            )
        if blen != BLOCK_LEN[btype]:
            clause = shape.clause if btype is BlockType.EMPTY else BLOCK_CLAUSE[btype]
            return self._fail(
                ShapeError, f"block type 0x{bt:02X} needs block length {BLOCK_LEN[btype]}, got {blen}",
                data, 8, clause,
            )
        want_n = str(shape.low) if shape.low == shape.high else f"{shape.low}..{shape.high}"
        return self._fail(ShapeError, f"{action.name} {role} needs {want_n} blocks, got {count}", data, 7, shape.clause)

    def _parse_blocks(self, data: bytes, btype: int, count: int) -> tuple[Block, ...]:
        """B3 indexes and B4 floats of ``count`` blocks whose header already checked out."""
        first = self._first
        if not self._strict and data[HEADER_LEN] in (0, 1):
            first = data[HEADER_LEN]  # lenient: accept either reading of B3
        strict = self._strict
        blocks: list[Block] = []
        if btype == BlockType.POSE:
            flat = self._pose_run(count).unpack_from(data, HEADER_LEN)  # index, x..r, index, x..r, ...
            indexes = flat[0::7]
            if indexes != _index_run(first, count):
                i = next(i for i, got in enumerate(indexes) if got != first + i)
                raise self._index_error(data, HEADER_LEN + i * POSE_BLOCK_LEN, indexes[i], first + i)
            if strict and not isfinite(sum(flat)):  # the indexes are finite: only the floats count
                i = next(i for i in range(count) if not isfinite(sum(flat[7 * i + 1 : 7 * i + 7])))
                raise self._fail(FloatError, f"block {i}: non-finite pose value", data, HEADER_LEN + i * 25 + 1)
            return new_pose_blocks(flat, count)
        is_tolerance = btype == BlockType.TOLERANCE
        unpack = (self.tolerance if is_tolerance else self.value).unpack_from
        for i in range(count):
            offset = HEADER_LEN + i * TOLERANCE_BLOCK_LEN
            index, value = unpack(data, offset)
            if index != first + i:
                raise self._index_error(data, offset, index, first + i)
            if is_tolerance:
                if strict and not isfinite(value):
                    raise self._fail(FloatError, f"block {i}: non-finite tolerance {value}", data, offset + 1)
                blocks.append(ToleranceBlock(index, value))
            else:
                blocks.append(ValueBlock(index, value))
        return tuple(blocks)

    def _pose_run(self, count: int) -> struct.Struct:
        """A struct for ``count`` consecutive pose blocks (cached; at most 255 of them)."""
        run = self._pose_runs.get(count)
        if run is None:
            run = self._pose_runs[count] = struct.Struct(self._float_order + "B6f" * count)
        return run

    def _index_error(self, data: bytes, offset: int, got: int, want: int) -> ProtocolError:
        return self._fail(BlockIndexError, f"block index {got}, expected {want}", data, offset)


_CODECS: dict[Profile, Codec] = {}
_INDEX_RUNS: dict[tuple[int, int], tuple[int, ...]] = {}


def _index_run(first: int, count: int) -> tuple[int, ...]:
    """B3: the indexes ``count`` blocks must carry, from ``first`` (cached)."""
    run = _INDEX_RUNS.get((first, count))
    if run is None:
        run = _INDEX_RUNS[(first, count)] = tuple(range(first, first + count))
    return run


def codec_for(profile: Profile = DEFAULT_PROFILE) -> Codec:
    """The compiled codec of a profile (cached)."""
    codec = _CODECS.get(profile)
    if codec is None:
        if len(_CODECS) > 64:
            _CODECS.clear()
        codec = _CODECS[profile] = Codec(profile)
    return codec


def _length_text(size: int, count: int, blen: int) -> str:
    """F5: a frame whose size is not what its header's N and L make."""
    return f"{size} bytes, but N={count} L={blen} make the frame 12+{count}*{blen}+2 = {HEADER_LEN + count * blen + CHECK_LEN}"

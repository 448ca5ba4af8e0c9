"""A scapy layer for the iSight frame (PROTOCOL.md F, B, E1).

This is a second, independent reading of the wire format, written with scapy's own
idioms, so that captures (pcaps) and golden vectors can be cross-checked against the
suite's codec. It dissects *any* bytes without raising: a short frame keeps the
fields that fit (the others are absent, ``to_dict`` reports them as ``None``); a block
length that does not match the block type gives raw blocks of L bytes each.

Layout (big-endian)::

    FE FE | 00 01 | transfer type | action | block type | N | L (2) | error (2)
    | N blocks of L bytes | check (2: TCP 00 00, UDP CRC-16)

Bytes after the check field of one frame are the next frame: on a TCP segment that
carries several frames they dissect as consecutive :class:`ISight` layers (a remainder
that does not start with FE FE is left as ``Raw``).

Only TCP and UDP port 9004 are bound on import; :func:`bind_port` adds another.
Importing this module prints nothing and does no network I/O.
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from typing import Any

from scapy.config import conf
from scapy.fields import (
    ByteEnumField,
    ByteField,
    FieldLenField,
    IEEEFloatField,
    MayEnd,
    PacketListField,
    SignedIntField,
    StrLenField,
    XShortEnumField,
    XShortField,
)
from scapy.layers.inet import TCP, UDP
from scapy.packet import Packet, bind_bottom_up, bind_layers, split_bottom_up

from conformance.protocol.codec import codec_for
from conformance.protocol.constants import (
    BLOCK_LEN,
    CHECK_LEN,
    DEFAULT_PORT,
    HEADER_FIELDS,
    HEADER_LEN,
    MAX_BLOCK_COUNT,
    START_BYTES,
    START_WORD,
    VERSION,
    Action,
    BlockType,
    ErrorCode,
    TransferType,
)
from conformance.protocol.profile import DEFAULT_PROFILE, Profile, crc_function

__all__ = [
    "ISight",
    "ISightBlock",
    "ISightPose",
    "ISightTolerance",
    "ISightValue",
    "ISightRawBlock",
    "bind_port",
    "unbind_port",
    "crc16",
    "with_udp_crc",
    "crc_ok",
    "to_dict",
    "from_dict",
    "frames",
]


def _names(enum_cls: Any) -> dict[int, str]:
    return {int(m): m.name.lower() for m in enum_cls}


TRANSFER_TYPES = _names(TransferType)
ACTIONS = _names(Action)
BLOCK_TYPES = _names(BlockType)
ERROR_CODES = _names(ErrorCode)

#: The layer's fields are big-endian (scapy's ShortField): the default profile's byte order.
_LAYOUT = codec_for(DEFAULT_PROFILE)
#: Most ISight layers chained on one packet. Scapy dissects, builds and shows a
#: packet by recursion, one level per layer, so a deep chain would hit Python's
#: recursion limit; past this many the rest stays Raw and :func:`frames` goes on.
MAX_CHAIN = 128

# Offsets at which a header field ends: a short frame is cut back to one of these.
_HEADER_FIELD_ENDS = (*(offset for offset, _width in HEADER_FIELDS.values()), HEADER_LEN)


# -- blocks ------------------------------------------------------------------------


class ISightBlock(Packet):
    """Base of the block layers. Dissecting through it (as the ``blocks`` field does)
    picks the layer from the parent frame's block type *and* block length."""

    name = "iSight block"
    fields_desc = [ByteField("index", 0)]

    def extract_padding(self, s: bytes) -> tuple[bytes, bytes]:
        # A block is exactly its fields; what follows is the next block.
        return b"", s

    @classmethod
    def dispatch_hook(cls, _pkt: bytes | None = None, *args: Any, **kargs: Any) -> type:
        parent = kargs.get("_parent")
        if not _pkt or parent is None:
            return cls
        return _block_class(parent.block_type, parent.block_length, len(_pkt))


def _f32(name: str) -> IEEEFloatField:
    """A big-endian float32 field (scapy's stub types the default as int)."""
    return IEEEFloatField(name, 0.0)  # type: ignore[arg-type]


class ISightPose(ISightBlock):
    """B1: index + x, y, z, w, p, r as float32 (L = 25)."""

    name = "iSight pose block"
    fields_desc = [
        ByteField("index", 0),
        _f32("x"),
        _f32("y"),
        _f32("z"),
        _f32("w"),
        _f32("p"),
        _f32("r"),
    ]


class ISightTolerance(ISightBlock):
    """B2: index + tolerance as float32 (L = 5)."""

    name = "iSight tolerance block"
    fields_desc = [ByteField("index", 0), _f32("tolerance")]


class ISightValue(ISightBlock):
    """E1: index + signed int32 (L = 5): a program index or a result code."""

    name = "iSight value block"
    fields_desc = [ByteField("index", 0), SignedIntField("value", 0)]


def _raw_block_len(pkt: Packet) -> int:
    # Inside a frame a raw block is L bytes; on its own it takes everything.
    parent = pkt.parent
    return parent.block_length if parent is not None else 1 << 31


class ISightRawBlock(ISightBlock):
    """A block whose (type, L) is not one of B1/B2/E1, or a truncated last block."""

    name = "iSight raw block"
    fields_desc = [StrLenField("data", b"", length_from=_raw_block_len)]


_BLOCK_CLASSES: dict[tuple[int, int], type[ISightBlock]] = {
    (BlockType.POSE, BLOCK_LEN[BlockType.POSE]): ISightPose,
    (BlockType.TOLERANCE, BLOCK_LEN[BlockType.TOLERANCE]): ISightTolerance,
    (BlockType.VALUE, BLOCK_LEN[BlockType.VALUE]): ISightValue,
}
_BLOCK_TYPE_OF = {cls: bt for (bt, _), cls in _BLOCK_CLASSES.items()}


def _block_class(block_type: int | None, block_length: int | None, available: int) -> type:
    cls = _BLOCK_CLASSES.get((block_type or 0, block_length or 0), ISightRawBlock)
    if available < (block_length or 0):
        return ISightRawBlock  # the segment ends inside this block
    return cls


# -- the frame ---------------------------------------------------------------------


class _BlockTypeField(ByteEnumField):
    """Block type; ``None`` (the default) means "the type of the first block"."""

    def i2m(self, pkt: Packet | None, x: Any) -> int:
        if x is None and pkt is not None:
            blocks = pkt.getfieldval("blocks") or []
            return int(_BLOCK_TYPE_OF.get(type(blocks[0]), 0)) if blocks else 0
        return super().i2m(pkt, x)


def _per_block(pkt: Packet, total: int) -> int:
    blocks = pkt.getfieldval("blocks") or []
    return total // len(blocks) if blocks else 0


def _blocks_len(pkt: Packet) -> int:
    return (pkt.block_count or 0) * (pkt.block_length or 0)


def _complete_len(s: bytes) -> int:
    """How much of ``s`` dissects into whole fields (scapy raises on half a field)."""
    n = len(s)
    if n < HEADER_LEN:
        return max(end for end in _HEADER_FIELD_ENDS if end <= n)
    end = _LAYOUT.frame_length(s) - CHECK_LEN
    if n <= end or n >= end + CHECK_LEN:
        return n  # blocks take what there is / the whole frame (and what follows)
    return end  # one stray byte of the check field


class ISight(Packet):
    """One iSight frame. ``block_type``, ``block_count`` and ``block_length`` are
    computed from ``blocks`` when left at ``None``; set them to craft bad frames.
    ``check`` defaults to 0 (TCP); see :func:`with_udp_crc` for UDP."""

    name = "iSight"
    fields_desc = [
        MayEnd(XShortField("start_word", int(START_WORD))),
        MayEnd(XShortField("version", int(VERSION))),
        MayEnd(ByteEnumField("transfer_type", int(TransferType.ROBOT_TO_BOX), TRANSFER_TYPES)),
        MayEnd(ByteEnumField("action", int(Action.NONE), ACTIONS)),
        MayEnd(_BlockTypeField("block_type", None, BLOCK_TYPES)),
        MayEnd(FieldLenField("block_count", None, count_of="blocks", fmt="B")),
        MayEnd(FieldLenField("block_length", None, length_of="blocks", fmt="H", adjust=_per_block)),
        MayEnd(XShortEnumField("error_code", int(ErrorCode.OK), ERROR_CODES)),
        MayEnd(PacketListField("blocks", [], ISightBlock, length_from=_blocks_len, max_count=MAX_BLOCK_COUNT)),
        XShortField("check", 0),
    ]

    def do_dissect(self, s: bytes) -> bytes:
        cut = _complete_len(s)
        if cut == 0:  # not even a start word: an empty layer, the byte goes to Raw
            self.raw_packet_cache = b""
            self.raw_packet_cache_fields = {}
            self.explicit = 1
            return s
        return super().do_dissect(s[:cut]) + s[cut:]

    def guess_payload_class(self, payload: bytes) -> type:
        if payload[:2] == START_BYTES and self._chain_position() < MAX_CHAIN - 1:
            return ISight
        return conf.raw_layer

    def _chain_position(self) -> int:
        n, under = 0, self.underlayer
        while isinstance(under, ISight):
            n, under = n + 1, under.underlayer
        return n

    def mysummary(self) -> str:
        if "check" not in self.fields and self.raw_packet_cache is not None:
            return f"iSight truncated frame ({len(self.raw_packet_cache)} bytes)"
        return self.sprintf(
            "iSight %transfer_type% %action% N=%block_count% L=%block_length% err=%error_code%"
        )


# -- ports -------------------------------------------------------------------------

_PORT_FIELDS = ("sport", "dport")


def bind_port(port: int) -> None:
    """Dissect TCP and UDP traffic from or to ``port`` as iSight."""
    for lower in (TCP, UDP):
        for fld in _PORT_FIELDS:
            if ({fld: port}, ISight) not in lower.payload_guess:
                bind_bottom_up(lower, ISight, **{fld: port})


def unbind_port(port: int) -> None:
    """Stop dissecting TCP and UDP traffic on ``port`` as iSight (building with
    ``TCP()/ISight()`` still fills in dport 9004)."""
    for lower in (TCP, UDP):
        for fld in _PORT_FIELDS:
            split_bottom_up(lower, ISight, **{fld: port})


for _lower in (TCP, UDP):
    bind_layers(_lower, ISight, sport=DEFAULT_PORT)
    bind_layers(_lower, ISight, dport=DEFAULT_PORT)  # last: TCP()/ISight() gets dport 9004
del _lower


# -- CRC (F7) ----------------------------------------------------------------------


def crc16(data: bytes, algorithm: str = "modbus") -> int:
    """CRC-16 of ``data`` under a crcmod predefined 16-bit algorithm name."""
    return crc_function(algorithm)(bytes(data))


def _frame_bytes(frame: Packet | bytes | bytearray) -> bytes:
    """The bytes of one frame: the first ISight layer, without what follows it."""
    if isinstance(frame, (bytes, bytearray)):
        return bytes(frame)
    layer = frame if isinstance(frame, ISight) else frame.getlayer(ISight)
    if layer is None:
        raise ValueError("no ISight layer in this packet")
    return bytes(layer.clone_with(**layer.fields))  # the same layer, without its payload


def with_udp_crc(pkt: Packet | bytes | bytearray, profile: Profile = DEFAULT_PROFILE) -> bytes:
    """The frame's bytes with its last two bytes (the check field) replaced by the
    CRC-16 of everything before them, as a UDP sender writes it (the profile's CRC)."""
    raw = _frame_bytes(pkt)
    if len(raw) < HEADER_LEN + CHECK_LEN:
        raise ValueError(f"a frame is at least {HEADER_LEN + CHECK_LEN} bytes, not {len(raw)}")
    body = raw[:-CHECK_LEN]
    return body + profile.check_bytes(body)


def crc_ok(raw: Packet | bytes | bytearray, profile: Profile = DEFAULT_PROFILE) -> bool:
    """True when the check field, found where the header puts it (12 + N*L), holds
    the profile's CRC-16 of bytes 0 .. 12+N*L-1. Bytes after the frame are not looked at."""
    raw = _frame_bytes(raw)
    if len(raw) < HEADER_LEN:
        return False
    end = _LAYOUT.frame_length(raw) - CHECK_LEN
    if len(raw) < end + CHECK_LEN:
        return False
    return raw[end : end + CHECK_LEN] == profile.check_bytes(raw[:end])


# -- the vector format ---------------------------------------------------------------

_HEADER_KEYS = (
    ("startWord", "start_word"),
    ("version", "version"),
    ("transferType", "transfer_type"),
    ("action", "action"),
    ("blockType", "block_type"),
    ("blockCount", "block_count"),
    ("blockLength", "block_length"),
    ("errorCode", "error_code"),
)
_POSE_AXES = ("x", "y", "z", "w", "p", "r")


def _block_dict(block: Packet) -> dict[str, Any]:
    if isinstance(block, ISightPose):
        return {"index": block.index, "pose": [float(block.getfieldval(a)) for a in _POSE_AXES]}
    if isinstance(block, ISightTolerance):
        return {"index": block.index, "tolerance": float(block.tolerance)}
    if isinstance(block, ISightValue):
        return {"index": block.index, "value": int(block.value)}
    return {"raw": bytes(block).hex()}


def to_dict(pkt: Packet) -> dict[str, Any]:
    """The first iSight frame in ``pkt`` in the vector format (``vectors/frames``).

    It describes the bytes on the wire: a built packet is serialised and read back,
    so computed fields have their values. A field the bytes did not reach is
    ``None``. Blocks that are neither B1, B2 nor E1 appear as ``{"raw": hex}``.
    ``check`` is the field as on the wire, read big-endian whatever the CRC byte order.
    """
    layer = pkt if isinstance(pkt, ISight) else pkt.getlayer(ISight)
    if layer is None:
        raise ValueError("no ISight layer in this packet")
    wire = ISight(_frame_bytes(layer))
    out: dict[str, Any] = {key: wire.fields.get(name) for key, name in _HEADER_KEYS}
    out["check"] = wire.fields.get("check")
    out["blocks"] = [_block_dict(b) for b in wire.fields.get("blocks", [])]
    return out


def _block_from_dict(d: Mapping[str, Any]) -> ISightBlock:
    # float() also reads the vectors' "NaN", "Infinity" and "-Infinity".
    if "pose" in d:
        axes: dict[str, Any] = dict(zip(_POSE_AXES, map(float, d["pose"]), strict=True))
        return ISightPose(index=d["index"], **axes)
    if "tolerance" in d:
        return ISightTolerance(index=d["index"], tolerance=float(d["tolerance"]))
    if "value" in d:
        return ISightValue(index=d["index"], value=int(d["value"]))
    if "raw" in d:
        return ISightRawBlock(data=bytes.fromhex(d["raw"]))
    raise ValueError(f"unknown block {dict(d)!r}")


def from_dict(frame: Mapping[str, Any]) -> ISight:
    """Build an :class:`ISight` from a vector-format dict; keys left out (or ``None``)
    take the layer's defaults, so ``blockCount`` etc. are then computed. A NaN is written as the quiet NaN 7FC00000: the
    dict does not carry a NaN's sign or payload."""
    fields = {name: frame[key] for key, name in _HEADER_KEYS if frame.get(key) is not None}
    if frame.get("check") is not None:
        fields["check"] = frame["check"]
    blocks = [_block_from_dict(b) for b in frame.get("blocks", [])]
    return ISight(blocks=blocks, **fields)


def frames(pkt: Packet | bytes | bytearray) -> Iterator[ISight]:
    """Every frame of a segment (a packet holding ISight, or the payload bytes), in
    order. Past :data:`MAX_CHAIN` frames the rest is dissected afresh, so a large
    (offloaded, loopback) segment yields all its frames."""
    if isinstance(pkt, (bytes, bytearray)):
        layer: Any = ISight(bytes(pkt)) if pkt else None
    else:
        layer = pkt if isinstance(pkt, ISight) else pkt.getlayer(ISight)
    while isinstance(layer, ISight):
        yield layer
        nxt = layer.payload
        if isinstance(nxt, conf.raw_layer) and nxt.load[:2] == START_BYTES:
            nxt = ISight(nxt.load)
        layer = nxt

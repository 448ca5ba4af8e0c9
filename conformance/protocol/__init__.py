"""The iSight protocol, sans-I/O: bytes in, frames and typed errors out.

No sockets, threads or clocks live in this package (like h11 and wsproto).
"""

from .api import (
    decode_datagram,
    encode,
    encode_block,
    encode_body,
    encode_header,
    encode_raw,
    encode_tcp,
    encode_udp,
    parse_frame,
    parse_header,
)
from .codec import Codec, codec_for
from .constants import (
    ACTION_ERROR,
    ANSWER_SHAPE,
    BLOCK_LEN,
    DEFAULT_PORT,
    EXTENSION_ACTIONS,
    HEADER_LEN,
    MAX_FRAME_LEN,
    REQUEST_SHAPE,
    Action,
    BlockType,
    ErrorCode,
    ResultCode,
    TransferType,
    Transport,
    action_name,
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
    answer,
    pose_blocks,
    request,
    tolerance_blocks,
    value_blocks,
)
from .profile import DEFAULT_PROFILE, ByteOrder, Profile, TcpCheckPolicy, crc16_names, crc_function
from .splitter import (
    HeaderPeek,
    Piece,
    PieceKind,
    Splitter,
    find_plausible_header,
    frame_span,
    frame_spanner,
    header_field_bytes,
    peek_action,
    peek_header,
    peek_transfer_type,
    split_bytes,
    whole_frames,
)
from .stream import CLOSED, NEED_DATA, Event, StreamDecoder

__all__ = [
    "ACTION_ERROR", "AnswerError", "ANSWER_SHAPE", "BLOCK_LEN", "ByteOrder", "CLOSED", "DEFAULT_PORT", "DEFAULT_PROFILE",
    "EXTENSION_ACTIONS", "HEADER_LEN", "MAX_FRAME_LEN", "NEED_DATA", "REQUEST_SHAPE",
    "Action", "action_name", "Block", "BlockIndexError", "BlockType", "CheckError", "Codec", "DirectionError",
    "ErrorCode", "Event", "FloatError", "Frame", "Header", "LengthError", "PoseBlock", "Profile",
    "ProtocolError", "ResultCode", "ShapeError", "StartWordError", "StreamDecoder", "TcpCheckPolicy",
    "ToleranceBlock", "Transport", "TransferType", "UnknownActionError", "ValueBlock", "VersionError",
    "answer", "codec_for", "crc16_names", "crc_function", "decode_datagram", "encode", "encode_block",
    "encode_body", "encode_header", "encode_raw", "encode_tcp", "encode_udp", "parse_frame",
    "parse_header", "pose_blocks", "request", "tolerance_blocks", "value_blocks",
    "HeaderPeek", "Piece", "PieceKind", "Splitter", "find_plausible_header", "frame_span", "frame_spanner",
    "header_field_bytes", "peek_action", "peek_header", "peek_transfer_type", "split_bytes",
    "whole_frames",
]

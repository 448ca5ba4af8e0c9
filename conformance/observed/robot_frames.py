"""What the robot sent, decoded from the transcripts (sans-I/O).

:func:`decode_conn` replays a connection's ``recv`` chunks through the codec's
:class:`~conformance.protocol.StreamDecoder` (``expect=ROBOT_TO_BOX``) and gives one
:class:`FrameRecord` per event with the time its last byte arrived. The judging
profile is the run's profile with ``tcp_check=zero``: a TCP *sender* MUST send 00 00
(F6), whatever a receiver tolerates. :func:`byte_order_evidence` is the F4 heuristic
(values absurd as read, plausible byte-swapped).
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass

from ..harness.transcript import Kind, Transcript
from ..protocol import (
    Frame,
    Profile,
    ProtocolError,
    StreamDecoder,
    TcpCheckPolicy,
    TransferType,
    decode_datagram,
    peek_header,
)
from ..protocol.codec import Codec, codec_for
from ..protocol.constants import (
    HEADER_LEN,
    POSE_BLOCK_LEN,
    START_WORD,
    TOLERANCE_BLOCK_LEN,
    VALUE_BLOCK_LEN,
    VERSION,
    Action,
    BlockType,
)
from .connections import ConnRecord

#: The actions whose blocks carry floats, and their (block type, block length).
_FLOAT_ACTIONS = {Action.POSE: (BlockType.POSE, POSE_BLOCK_LEN), Action.REGISTER_POSE: (BlockType.POSE, POSE_BLOCK_LEN),
                  Action.TOLERANCE: (BlockType.TOLERANCE, TOLERANCE_BLOCK_LEN)}
#: A pose value (mm or degrees) or a tolerance beyond this is not plausible.
PLAUSIBLE_MAX = 1e6
#: Values of at least this magnitude count as evidence (other-endian floats read as ~1e-40).
PLAUSIBLE_MIN = 1e-6


def judge_profile(profile: Profile) -> Profile:
    """The profile frames are judged with: a TCP sender MUST send check 00 00 (F6)."""
    return profile.replace(tcp_check=TcpCheckPolicy.ZERO)


@dataclass(frozen=True)
class FrameRecord:
    """One decoder event from the robot: a frame or a ProtocolError, with its bytes."""

    conn: int
    transport: str
    t: float
    offset: int
    raw: bytes
    event: Frame | ProtocolError

    @property
    def error(self) -> ProtocolError | None:
        return self.event if isinstance(self.event, ProtocolError) else None

    @property
    def action(self) -> int | None:
        """The action, when the bytes have a readable request-like header (FE FE, 00 01)."""
        if isinstance(self.event, Frame):
            return int(self.event.action)
        header = self.event.header
        if header is None or header.start_word != START_WORD or header.version != VERSION:
            return None
        return int(header.action)

    @property
    def header_ok(self) -> bool:
        """Start word and version readable: the frame's other fields can be judged."""
        return self.action is not None

    def describe(self) -> str:
        if isinstance(self.event, Frame):
            return self.event.describe()
        return f"[{self.event.clause}] {self.event.message}"


def decode_conn(conn: ConnRecord, profile: Profile) -> list[FrameRecord]:
    """Every event of what the robot sent on ``conn`` (a TCP stream or UDP datagrams)."""
    judged = judge_profile(profile)
    if conn.transport == "udp":
        out = []
        for n, ev in enumerate(e for e in conn.transcript.events if e.kind == Kind.RECV):
            try:
                event: Frame | ProtocolError = decode_datagram(ev.data, judged, TransferType.ROBOT_TO_BOX)
            except ProtocolError as exc:
                event = exc
            out.append(FrameRecord(conn.number, "udp", ev.t, n, ev.data, event))
        return out
    return decode_stream(conn.transcript, judged, conn.number)


def decode_stream(transcript: Transcript, profile: Profile, conn: int = 1) -> list[FrameRecord]:
    """The robot's TCP bytes (``recv`` events), frame by frame, each with its arrival time."""
    decoder = StreamDecoder(profile, TransferType.ROBOT_TO_BOX)
    stream = bytearray()
    out: list[FrameRecord] = []

    def drain(t: float) -> None:
        while True:
            start = decoder.offset
            event = decoder.next_event()
            if not isinstance(event, (Frame, ProtocolError)):
                return
            out.append(FrameRecord(conn, "tcp", t, start, bytes(stream[start:decoder.offset]), event))

    last = 0.0
    for ev in transcript.events:
        if ev.kind == Kind.RECV and ev.data and not decoder.eof:
            stream += ev.data
            decoder.receive_data(ev.data)
            last = ev.t
            drain(ev.t)
        elif ev.kind in (Kind.PEER_CLOSE, Kind.PEER_RESET) and not decoder.eof:
            decoder.receive_data(b"")
            drain(last or ev.t)  # a truncated frame's bytes arrived before the close
    return out


# -- F4: the byte-order heuristic ----------------------------------------------------------------
def _reading(values: Iterable[float]) -> tuple[bool, int]:
    """(absurd, normal): a reading is absurd with a non-finite value or one beyond
    PLAUSIBLE_MAX; ``normal`` counts values of a plausible magnitude (residues like
    1e-17 and zeros count for neither reading)."""
    values = list(values)
    absurd = any(not math.isfinite(v) or abs(v) > PLAUSIBLE_MAX for v in values)
    return absurd, sum(1 for v in values if math.isfinite(v) and PLAUSIBLE_MIN <= abs(v) <= PLAUSIBLE_MAX)


def compare_readings(straight: Iterable[float], swapped: Iterable[float]) -> str | None:
    """``straight``, ``swapped`` or None (no evidence either way)."""
    bad_a, n_a = _reading(straight)
    bad_b, n_b = _reading(swapped)
    if not bad_a and n_a and n_a >= n_b:
        return "straight"
    if not bad_b and n_b > n_a and (bad_a or 2 * n_a < n_b):
        return "swapped"
    return None


def byte_order_evidence(rec: FrameRecord, profile: Profile) -> str | None:
    """``"swapped"`` when the frame reads as absurd under the profile's byte order but
    plausible in the other one, ``"straight"`` when it reads plausibly, None when the
    frame says nothing about byte order (no values, all zero, not a whole frame)."""
    raw = rec.raw
    head = peek_header(raw, 0, profile.byte_order)
    if len(raw) < HEADER_LEN + 2 or head is None or not head.start_ok:
        return None
    if not head.version_ok:
        flipped = peek_header(raw, 0, profile.swapped(header=True).byte_order)
        return "swapped" if flipped is not None and flipped.version_ok else None
    codec = codec_for(profile)
    header = codec.parse_header(raw)
    if len(raw) != codec.frame_length(raw) or not header.block_count:
        return None
    other = codec_for(profile.swapped(floats=True))
    shape = (header.block_type, header.block_length)
    if header.action in _FLOAT_ACTIONS and shape == _FLOAT_ACTIONS[Action(header.action)]:
        straight: list[float] = []
        swapped: list[float] = []
        for at in range(HEADER_LEN, HEADER_LEN + header.block_count * header.block_length, header.block_length):
            straight += _block_values(codec, header.block_type, raw, at)
            swapped += _block_values(other, header.block_type, raw, at)
        return compare_readings(straight, swapped)
    if header.action == Action.PROG_IDX and shape == (BlockType.VALUE, VALUE_BLOCK_LEN):
        value, value_swapped = codec.value.unpack_from(raw, HEADER_LEN)[1], other.value.unpack_from(raw, HEADER_LEN)[1]
        if value == 0:
            return None
        if 0 < abs(value) <= 0xFFFF:
            return "straight"
        return "swapped" if 0 < abs(value_swapped) <= 0xFFFF else None
    return None


def _block_values(codec: Codec, block_type: int, raw: bytes, at: int) -> tuple[float, ...]:
    """A pose or tolerance block's floats at ``at``, read with ``codec``'s float byte order."""
    block = codec.pose if block_type == BlockType.POSE else codec.tolerance
    return tuple(block.unpack_from(raw, at)[1:])

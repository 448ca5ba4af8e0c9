"""One TCP connection of the reference box, sans-I/O: ``receive_data(bytes) -> answer bytes``.

:class:`BoxConnection` frames bytes with the codec's :class:`~conformance.protocol.StreamDecoder`
and asks :meth:`.behaviour.BoxBehaviour.decide`; it has a fast path for the stream's hot case
(whole, valid one-pose frames -> the cached 0000 answer, many at once). No sockets or clocks:
:mod:`.protocols` feeds it from asyncio, certify from its listener.
"""

from __future__ import annotations

from math import isfinite

from ..protocol import Action, Frame, ProtocolError, StreamDecoder, TransferType, pose_blocks, request
from ..protocol.constants import MAX_FRAME_LEN
from .behaviour import BoxBehaviour, Reaction, Tracer


class BoxConnection:
    """One TCP connection, sans-I/O: ``receive_data(bytes) -> answer bytes``.

    Whole valid one-pose frames at a frame boundary take a fast path (no decoder,
    no Frame objects, the cached answer, k frames checked together with C-level
    slicing). Anything else goes through the codec's StreamDecoder and
    :meth:`BoxBehaviour.decide`. The two agree byte for byte (the tests check it).
    """

    __slots__ = (
        "behaviour", "trace", "should_close", "close_reason", "_decoder", "_slow", "_pending", "_fast", "_head", "_ok",
        "_exp", "_mirror", "_mirror_base", "frames_in", "_floats", "_strict",
    )

    def __init__(self, behaviour: BoxBehaviour, trace: Tracer | None = None) -> None:
        self.behaviour = behaviour
        self.trace = trace
        self.should_close = False
        self.close_reason = ""
        self._decoder: StreamDecoder | None = None
        self._slow = False  # the decoder holds bytes: everything goes to it
        self._pending = b""  # fast path: the start of a frame (< 39 bytes)
        profile = behaviour.profile
        codec = behaviour.codec
        sample = codec.encode(request(Action.POSE, pose_blocks([(0.0,) * 6], profile.first_index)))
        self._head = sample[:13]  # header + first block index
        self._ok = behaviour.pose_ok
        self._strict = profile.strict
        # the byte of each float32 that holds the sign and the high exponent bits
        self._exp = tuple(13 + 4 * j + (0 if profile.float_byte_order == "big" else 3) for j in range(6))
        self._floats = codec.pose.unpack_from
        # the fast path needs the decision for a pose to be the constant 0000 of decide()
        self._fast = trace is None and bool(self._ok) and behaviour.fast_path
        self._mirror = bytearray()
        self._mirror_base = 0
        self.frames_in = 0

    @property
    def buffered(self) -> int:
        """Bytes received and not yet decided (at most one partial frame)."""
        return len(self._pending) + (self._decoder.buffered if self._decoder is not None else 0)

    def receive_data(self, data: bytes) -> bytes:
        """Bytes from the robot in, every answer they complete out (b"" for none).

        ``should_close`` is set when the box decided to close the connection.
        """
        if self._fast and not self._slow:
            buf = self._pending + data if self._pending else data
            size = len(buf)
            if size == 39:  # the stream's steady state: exactly one pose frame
                if (
                    buf[:13] == self._head and buf[37] == 0 and buf[38] == 0
                    and (not self._strict or isfinite(sum(self._floats(buf, 12)[1:])))
                ):
                    self._pending = b""
                    self.frames_in += 1
                    self.behaviour.stats.requests += 1
                    self.behaviour.stats.answers += 1
                    return self._ok
            elif size > 39:
                count = size // 39
                if self._all_poses(buf, count):
                    end = count * 39
                    self._pending = buf[end:]
                    self.frames_in += count
                    self.behaviour.stats.requests += count
                    self.behaviour.stats.answers += count
                    if self._pending and not self._maybe_pose(self._pending):
                        rest, self._pending = self._pending, b""
                        return self._ok * count + self._slow_path(rest)
                    return self._ok * count
            elif self._maybe_pose(buf):
                self._pending = bytes(buf)
                return b""
            self._pending = b""
            return self._slow_path(buf)
        return self._slow_path(data)

    def _maybe_pose(self, buf: bytes) -> bool:
        """``buf`` (shorter than a pose frame) could be the start of a valid pose frame."""
        n = len(buf)
        return buf[:13] == self._head[:n] if n < 39 else False

    def _all_poses(self, buf: bytes, count: int) -> bool:
        """The first ``count`` 39-byte frames of ``buf`` are all valid one-pose requests."""
        end = count * 39
        head = self._head
        if count <= 8:  # a few frames (a robot that fell behind): frame by frame is cheaper
            exp = self._exp
            for start in range(0, end, 39):
                if buf[start : start + 13] != head or buf[start + 37] or buf[start + 38]:
                    return False
                if (
                    self._strict
                    and any(buf[start + off] in (0x7F, 0xFF) for off in exp)  # exponent may be all ones
                    and not isfinite(sum(self._floats(buf, start + 12)[1:]))
                ):
                    return False
            return True
        for off in range(13):  # header and block index: one strided slice per byte
            column = buf[off:end:39]
            if column.strip(head[off : off + 1]):
                return False
        if buf[37:end:39].strip(b"\x00") or buf[38:end:39].strip(b"\x00"):
            return False
        if self._strict:
            for off in self._exp:
                column = buf[off:end:39]
                if b"\x7f" in column or b"\xff" in column:  # exponent may be all ones: check exactly
                    unpack = self._floats
                    return all(isfinite(sum(unpack(buf, i)[1:])) for i in range(12, end, 39))
        return True

    def _slow_path(self, data: bytes) -> bytes:
        decoder = self._decoder
        if decoder is None:
            decoder = self._decoder = StreamDecoder(self.behaviour.profile, TransferType.ROBOT_TO_BOX)
            self._mirror_base = decoder.offset
        decoder.receive_data(data)
        decide = self.behaviour.decide
        trace = self.trace
        out: list[bytes] = []
        if trace is not None:
            self._mirror += data
        while True:
            start = decoder.offset
            event = decoder.next_event()
            if not isinstance(event, (Frame, ProtocolError)):  # NEED_DATA or CLOSED
                break
            self.frames_in += 1
            decision = decide(event)
            if trace is not None:
                base = self._mirror_base
                trace(bytes(self._mirror[start - base : decoder.offset - base]), event, decision)
            if decision.tcp is not None:
                out.append(decision.tcp)
            elif decision.reaction is Reaction.CLOSE:
                self.should_close = True
                self.close_reason = decision.note
                break
        if trace is not None:
            del self._mirror[: decoder.offset - self._mirror_base]
            self._mirror_base = decoder.offset
        self._slow = decoder.buffered > 0
        if decoder.buffered > MAX_FRAME_LEN:  # never: the decoder keeps at most one partial frame
            self.should_close = True
            self.close_reason = f"R5: {decoder.buffered} bytes undecided, more than one frame ({MAX_FRAME_LEN})"
        return b"".join(out)


__all__ = ["BoxConnection"]

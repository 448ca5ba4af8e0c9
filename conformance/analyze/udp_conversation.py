"""iSight over UDP: one datagram is one frame (F7), judged both ways.

A :class:`UdpConversation` is the datagrams between one robot address and port and
one box address and port. Each datagram goes through the codec's
:func:`~conformance.protocol.decode_datagram` (exactly one frame, the profile's CRC-16)
and then to the same :class:`~.exchanges.ConnJudge` as a TCP connection: answers are
paired with requests in order, a bad datagram the box drops is not missed (R7 says it
SHOULD be dropped), and 0000 to a bad datagram is R7's FAIL.

The CRC: when ``--crc`` was not given and a datagram's check fits another CRC-16
algorithm (or the other byte order) instead of the profile's, the capture shows which
reading the robot and box use; F7 is then INCONCLUSIVE with the flags to rerun with,
and the frame is judged under that reading. A datagram duplicated by a mirror port (the
same bytes again within a millisecond) is judged once.
"""

from __future__ import annotations

from ..model.verdicts import Verdict
from ..protocol import (
    CheckError,
    Frame,
    Profile,
    ProtocolError,
    TransferType,
    crc16_names,
    crc_function,
    decode_datagram,
)
from .analysis_context import Context
from .capture_packets import endpoints, format_endpoint
from .exchanges import ConnJudge
from .findings import BOX, ROBOT

__all__ = ["UdpConversation", "crc_reading"]

DUPLICATE_S = 0.001


def crc_reading(data: bytes, profile: Profile) -> tuple[str, str] | None:
    """(algorithm, byte order) of a CRC-16 that the datagram's check field fits, other than the profile's."""
    if len(data) < 14:
        return None
    body, check = data[:-2], data[-2:]
    for name in crc16_names():
        value = crc_function(name)(body)
        for order in ("big", "little"):
            if (name, order) != (profile.crc, profile.crc_byte_order) and value.to_bytes(2, order) == check:
                return name, order
    return None


class UdpConversation:
    def __init__(self, ctx: Context, key: bytes, robot_dir: int) -> None:
        self.ctx = ctx
        self.robot_dir = robot_dir
        a, b = endpoints(key)
        robot, box = (a, b) if robot_dir == 0 else (b, a)
        self.number = ctx.label()
        self.label = f"udp {self.number} ({format_endpoint(*robot)} → {format_endpoint(*box)})"
        self.judge = ConnJudge(ctx, self.label, "udp", box=box)
        self.offsets = [0, 0]  # datagram number per direction
        self.last: list[tuple[bytes, float] | None] = [None, None]
        self.reading: Profile | None = None  # another CRC the datagrams fit
        ctx.stats.udp_conversations += 1
        ctx.stats.robots.add(robot[0])
        ctx.stats.boxes.add(format_endpoint(*box) + "/udp")

    def datagram(self, d: int, payload: bytes, missing: int, no: int, ts: float) -> None:
        previous = self.last[d]
        if previous is not None and previous[0] == payload and ts - previous[1] < DUPLICATE_S:
            return
        self.last[d] = (payload, ts)
        robot = d == self.robot_dir
        side = ROBOT if robot else BOX
        expect = TransferType.ROBOT_TO_BOX if robot else TransferType.BOX_TO_ROBOT
        offset = self.offsets[d]
        self.offsets[d] += 1
        self.ctx.now = ts
        if missing:
            self.ctx.findings.tally("F7", side).note(f"frame {no}: datagram cut by the capture's snap length "
                                                     f"({missing} bytes missing): not judged")
            return
        profile = self.reading or self.ctx.judged
        try:
            event: Frame | ProtocolError = decode_datagram(payload, profile, expect)
        except ProtocolError as exc:
            event = exc
            if isinstance(exc, CheckError) and exc.clause == "F7" and not self.ctx.config.crc_stated:
                event = self._other_crc(payload, expect, exc, side, no)
        if robot:
            self.judge.request(event, payload, offset, no, no, ts)
        else:
            self.judge.answer(event, payload, offset, no, no, ts)

    def _other_crc(self, payload: bytes, expect: TransferType, exc: ProtocolError, side: str,
                   no: int) -> Frame | ProtocolError:
        reading = crc_reading(payload, self.ctx.profile)
        if reading is None:
            return exc
        name, order = reading
        self.reading = self.ctx.judged.replace(crc=name, crc_byte_order=order)
        self.ctx.findings.add("F7", side, Verdict.INCONCLUSIVE,
                              f"{self.label}: the check fields fit CRC-16 '{name}' ({order}-endian), not the "
                              f"profile's '{self.ctx.profile.crc}' ({self.ctx.profile.crc_byte_order}-endian); judged "
                              f"under that reading: rerun with --crc {name} --crc-byte-order {order} to judge F7",
                              (no,), **{side: payload})
        try:
            return decode_datagram(payload, self.reading, expect)
        except ProtocolError as again:
            return again

    def finish(self, ts: float) -> None:
        self.judge.finish("capture", ts, None, 0)


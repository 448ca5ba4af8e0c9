"""What a box answers to each framer event: the legal choices and the planted defects.

Sans-I/O. :class:`Choices` holds one box's choices where PROTOCOL.md allows several
and at most one planted defect; :func:`decide` turns a framer event into a
:class:`Reply` (bytes to write, a delay, or close/hang) and updates the cycle state.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass, field, replace

from . import wire
from .framers import Close, Event, Frame, Garbage, Rejected
from .wire import Check, Header

#: The planted defects (one per broken box) and the clause each breaks.
DEFECTS: dict[str, str] = {
    "swapped-version": "F2",
    "swapped-error": "A3",
    "wrong-transfer-type": "F3",
    "zero-to-malformed": "A3",
    "one-at-a-time": "S4",
    "leaky": "S5",
    "dead": "T1",
    "slow-bytes": "T1",
    "late-cycle-on": "T1",
    "flood-random": "R5",
    "flood-headers": "R5",
    "no-resync": "R6",
    "nan-zero": "B4",
    "drops-coalesced": "R4",
}


@dataclass(frozen=True)
class Choices:
    """One box's legal choices (and at most one defect)."""

    framing: str = "trust"  # fine | skip | trust | close (R6)
    check: Check = field(default_factory=Check)
    #: A5, frames that are not requests: silent | error (a non-zero answer) | close
    on_not_request: str = "silent"
    #: A3, malformed CycleOn/CycleOff: "error" (0001/0002) or "silent"
    malformed_cycle: str = "error"
    #: malformed 26/27: "silent", or "400" (ResultCode 400 in the block and the error field)
    malformed_ext: str = "silent"
    #: S3: cycle state per "box" or per "connection"; strict answers 0001/0002 out of order
    cycle_scope: str = "box"
    strict_cycle: bool = False
    #: how answers are written: "one" write, or "bytes" (one byte per send, 10 ms pause after the first)
    writer: str = "one"
    udp: bool = False
    vision_result: int = 1
    defect: str | None = None

    def __post_init__(self) -> None:
        if self.defect is not None and self.defect not in DEFECTS:
            raise ValueError(f"unknown defect {self.defect!r}")

    @property
    def extension(self) -> bool:
        return self.check.extension

    def with_defect(self, defect: str) -> Choices:
        """The same box with one switch flipped."""
        if defect == "nan-zero":
            return replace(self, defect=defect, check=replace(self.check, reject_nan=False))
        return replace(self, defect=defect)


class Cycle:
    """The cycle state (S2/S3); one per box or one per connection."""

    def __init__(self) -> None:
        self.on = False
        self.lock = threading.Lock()


@dataclass(frozen=True)
class Reply:
    data: bytes = b""
    delay: float = 0.0  # seconds to wait before writing (late-cycle-on)
    close: bool = False
    hang: bool = False  # stop answering on this connection (no-resync)


SILENT = Reply()
CLOSE = Reply(close=True)
HANG = Reply(hang=True)

_MALFORMED_CODE = {wire.POSE: wire.POSE_ERROR, wire.REG_POSE: wire.POSE_ERROR, wire.TOLERANCE: wire.TOL_ERROR,
                   wire.CYCLE_ON: wire.NOT_READY, wire.CYCLE_OFF: wire.OFF_FAILED}


def answer(choices: Choices, action: int, error: int = wire.OK, value: int | None = None) -> bytes:
    """An answer, with the planted encoding defects applied."""
    defect = choices.defect
    if defect == "swapped-error":
        error = ((error & 0xFF) << 8) | (error >> 8)
    return wire.encode(
        action, error, value,
        version=0x0100 if defect == "swapped-version" else wire.VERSION,
        transfer=wire.ROBOT_TO_BOX if defect == "wrong-transfer-type" else wire.BOX_TO_ROBOT,
        first_index=choices.check.first_index,
    )


def decide(choices: Choices, event: Event, cycle: Cycle) -> Reply:
    """The box's reaction to one framer event."""
    if isinstance(event, Close):
        return CLOSE
    if isinstance(event, Garbage):
        return HANG if choices.defect == "no-resync" else SILENT
    header = event.header
    if wire.not_a_request(header, choices.extension):
        return _not_request(choices, header)
    if isinstance(event, Rejected):  # a request header the framer would not take: B5 / implausible length
        return _malformed(choices, header)
    assert isinstance(event, Frame)
    if wire.request_ok(event.data, header, choices.check):
        return _well_formed(choices, header, event.data, cycle)
    if choices.defect == "zero-to-malformed" and header.action in (wire.POSE, wire.REG_POSE):
        return Reply(answer(choices, header.action))
    return _malformed(choices, header)


def _not_request(choices: Choices, header: Header) -> Reply:
    if choices.defect == "no-resync":
        return HANG
    if choices.on_not_request == "close":
        return CLOSE
    if choices.on_not_request == "error" and header.start == 0xFEFE:
        return Reply(answer(choices, header.action, 0xFFFF))  # "not understood", echoing the action byte
    return SILENT


def _malformed(choices: Choices, header: Header) -> Reply:
    action = header.action
    if action in (wire.POSE, wire.REG_POSE, wire.TOLERANCE):
        return Reply(answer(choices, action, _MALFORMED_CODE[action]))
    if action in (wire.CYCLE_ON, wire.CYCLE_OFF) and choices.malformed_cycle == "error":
        return Reply(answer(choices, action, _MALFORMED_CODE[action]))
    if action in wire.EXT_ACTIONS and choices.malformed_ext == "400":
        return Reply(answer(choices, action, 400, 400))
    return SILENT  # malformed NONE: A4 only defines 0000, which A3 forbids here


def _well_formed(choices: Choices, header: Header, frame: bytes, cycle: Cycle) -> Reply:
    action = header.action
    if action == wire.CYCLE_ON:
        with cycle.lock:
            error = wire.NOT_READY if choices.strict_cycle and cycle.on else wire.OK
            cycle.on = True
        return Reply(answer(choices, action, error), delay=6.0 if choices.defect == "late-cycle-on" else 0.0)
    if action == wire.CYCLE_OFF:
        with cycle.lock:
            error = wire.OFF_FAILED if choices.strict_cycle and not cycle.on else wire.OK
            cycle.on = False
        return Reply(answer(choices, action, error))
    if action == wire.PROG_IDX:
        value = int.from_bytes(frame[wire.HEADER_LEN + 1 : wire.HEADER_LEN + 5], "big", signed=True)
        return Reply(answer(choices, action, wire.OK, value))
    if action == wire.RESULT:
        return Reply(answer(choices, action, wire.OK, choices.vision_result))
    return Reply(answer(choices, action))


def decide_datagram(choices: Choices, data: bytes, cycle: Cycle) -> bytes | None:
    """R7/F7 over UDP: one frame per datagram with a CRC-16/MODBUS; bad datagrams are dropped."""
    if len(data) < wire.HEADER_LEN + wire.CHECK_LEN:
        return None
    header = Header.parse(data)
    if len(data) != header.frame_len or data[-2:] != wire.crc16_modbus(data[:-2]).to_bytes(2, "big"):
        return None
    tcp_like = data[:-2] + b"\0\0"
    reply = decide(choices, Frame(tcp_like, header), cycle)
    if not reply.data:
        return None
    return reply.data[:-2] + wire.crc16_modbus(reply.data[:-2]).to_bytes(2, "big")

"""What a box answers to each framer event: the legal choices (knobs) and the planted defects.

Sans-I/O. :data:`KNOBS` is the box's side of the legal-choice space
(``conformance/protocol/legal.py``): each knob takes exactly the alternatives of one
row there, and a test keeps the two in step. :class:`Choices` holds one value per knob
and at most one planted defect; :func:`random_choices` draws a legal combination from
a seed; :func:`decide` turns a framer event into a :class:`Reply` (bytes to write, a
delay, or close/hang) and updates the cycle state.
"""

from __future__ import annotations

import random
import threading
from dataclasses import dataclass, fields, replace

from . import systematic, udp_defects
from . import wire_format as wire
from .framers import Close, Event, Frame, Framing, Garbage, Rejected
from .wire_format import Check, Header

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
    # bounded time whatever the box does (issue 25)
    "sticky-error": "A4",
    "drops-frames": "A1",
    "answers-some-actions": "A1",
    "quiet-after-n": "T1",
    "short-send-drops": "S6",
    "latency-grows": "T2",
    # coverage found outside the catalogue (issue 36)
    "low-byte-length": "F4",
    "drops-unsendable": "S6",

    # bounded time on every box (issue 36): boxes of the kinds written outside this project took longest on
    "drops-rest-of-read": "R4",
    "split-header-lost": "R3",
    "stall-once": "T1",  # the whole box stops answering for 6 s, once (issue 34, item 3)
} | udp_defects.UDP_DEFECTS | udp_defects.CHECK_DEFECTS | {name: planted.clause for name, planted in systematic.SYSTEMATIC.items()}  # the root-cause benchmark's

_RESUME = ("resume+1", "resume+5", "resume+12")
#: knob -> its legal alternatives (the first is the default); the names are the legal table's knobs.
KNOBS: dict[str, tuple[str, ...]] = {
    "framing_garbage": ("scan", "close"),
    "framing_version": (*_RESUME, "close"),
    "framing_length": (*_RESUME, "close"),
    "framing_transfer": ("trust", *_RESUME, "close"),
    "framing_action": ("trust", *_RESUME, "close"),
    "framing_shape": ("trust", *_RESUME),
    "not_request": ("silent", "error", "close"),
    "refusal_action": ("echo", "00"),
    "refusal_code": ("FFFF", "0001", "1001"),
    "malformed_blockless": ("error", "silent", "close"),
    "malformed_ext": ("silent", "400"),
    "request_error_field": ("accept", "reject"),
    "tcp_check": ("ignore", "zero-or-crc"),
    "cycle_scope": ("box", "connection"),
    "cycle_on_twice": ("0000", "0001"),
    "cycle_off_idle": ("0000", "0002"),
    "cycle_on_ready": ("ready", "first-not-ready"),
    "extension": ("present", "absent"),
    "ext_refusal": ("silent", "error-echo", "error-00", "close"),
    "prog_idx": ("index", "409"),
    "vision_result": ("1", "2", "10", "20", "202", "409"),
    "progidx_conflict": ("block", "error-code"),
    "first_index": ("0", "1"),
    "nan": ("reject", "accept"),
    "udp": ("off", "on"),
    "writer": ("whole", "bytes", "pieces"),
    "latency": ("0", "2ms", "20ms", "100ms"),
    "cycle_on_latency": ("0", "0.6 time_out"),
    "stream_port": ("same", "separate"),
}

_ERRORS = {"0000": wire.OK, "0001": wire.NOT_READY, "0002": wire.OFF_FAILED, "1001": wire.POSE_ERROR,
           "FFFF": 0xFFFF}


@dataclass(frozen=True)
class Choices:
    """One box: a value per knob (each a legal alternative) and at most one defect."""

    framing_garbage: str = "scan"
    framing_version: str = "resume+1"
    framing_length: str = "resume+1"
    framing_transfer: str = "trust"
    framing_action: str = "trust"
    framing_shape: str = "trust"
    not_request: str = "silent"
    refusal_action: str = "echo"
    refusal_code: str = "FFFF"
    malformed_blockless: str = "error"
    malformed_ext: str = "silent"
    request_error_field: str = "accept"
    tcp_check: str = "ignore"
    cycle_scope: str = "box"
    cycle_on_twice: str = "0000"
    cycle_off_idle: str = "0000"
    cycle_on_ready: str = "ready"
    extension: str = "present"
    ext_refusal: str = "silent"
    prog_idx: str = "index"
    vision_result: str = "1"
    progidx_conflict: str = "block"
    first_index: str = "0"
    nan: str = "reject"
    udp: str = "off"
    writer: str = "whole"
    latency: str = "0"
    cycle_on_latency: str = "0"
    stream_port: str = "same"
    defect: str | None = None
    time_out: float = 5.0  # the time_out the box assumes (cycle_on_latency is a fraction of it)
    late: float = 0.0  # every answer this fraction of time_out late as well (no knob: legal below 1)
    #: no knob: a header with another version that announces no blocks is rejected only once its check field is
    #: read (12 bytes take the next two bytes as their check field; R6 b resumes after them)
    short_frames: bool = False

    def __post_init__(self) -> None:
        if self.defect is not None and self.defect not in DEFECTS:
            raise ValueError(f"unknown defect {self.defect!r}")
        for name, legal in KNOBS.items():
            if getattr(self, name) not in legal:
                raise ValueError(f"knob {name}: {getattr(self, name)!r} is not one of {', '.join(legal)}")

    @property
    def has_extension(self) -> bool:
        return self.extension == "present"

    @property
    def check(self) -> Check:
        return Check(extension=self.has_extension, first_index=int(self.first_index),
                     reject_nan=self.nan == "reject", ignore_check=self.tcp_check == "ignore",
                     reject_request_error=self.request_error_field == "reject")

    @property
    def framing(self) -> Framing:
        return Framing(self.framing_garbage, "frame" if self.short_frames else self.framing_version,
                       self.framing_length, self.framing_transfer, self.framing_action, self.framing_shape)

    def knobs(self) -> dict[str, str]:
        return {name: getattr(self, name) for name in KNOBS}

    def suite_args(self) -> tuple[str, ...]:
        """The profile flags a tester needs for this box's flag-decided choices (legal.py's ``flags``)."""
        args: list[str] = []
        if self.first_index != "0":
            args += ["--first-index", self.first_index]
        if self.nan == "accept" and self.defect != "nan-zero":
            args += ["--checking", "lenient"]
        if self.progidx_conflict == "error-code":
            args += ["--progidx-conflict", "error-code"]
        return tuple(args)

    def with_defect(self, defect: str) -> Choices:
        """The same box with one switch flipped."""
        if defect == "nan-zero":
            return replace(self, defect=defect, nan="accept")
        return replace(self, defect=defect)


def with_framing(choices: Choices, framing: Framing) -> Choices:
    return replace(choices, **{f"framing_{f.name}": getattr(framing, f.name) for f in fields(framing)})


def random_choices(seed: int, *, fixed: dict[str, str] | None = None) -> Choices:
    """A legal combination drawn from ``seed`` (the same seed, the same box); ``fixed`` knobs are kept."""
    rng = random.Random(seed)
    values = {}
    for name, legal in KNOBS.items():
        values[name] = rng.choice(legal)  # drawn for every knob, so a fixed one leaves the others unchanged
    return knob_choices(values | (fixed or {}))


def knob_choices(knobs: dict[str, str]) -> Choices:
    """A box from knob values (the defaults for the knobs not given)."""
    return replace(Choices(), **knobs)  # type: ignore[arg-type]  # every value is a knob string


class Cycle:
    """The cycle state (S2/S3); one per box or one per connection."""

    def __init__(self) -> None:
        self.on = False
        self.ready = True  # first-not-ready: False until the first CycleOn was refused
        self.lock = threading.Lock()


@dataclass(frozen=True)
class Reply:
    data: bytes = b""
    delay: float = 0.0  # seconds to wait before writing, beyond the box's latency
    close: bool = False
    hang: bool = False  # stop answering on this connection (no-resync)


SILENT = Reply()
CLOSE = Reply(close=True)
HANG = Reply(hang=True)

_MALFORMED_CODE = {wire.POSE: wire.POSE_ERROR, wire.REG_POSE: wire.POSE_ERROR, wire.TOLERANCE: wire.TOL_ERROR,
                   wire.CYCLE_ON: wire.NOT_READY, wire.CYCLE_OFF: wire.OFF_FAILED, wire.NONE: 0xFFFF}


def answer(choices: Choices, action: int, error: int = wire.OK, value: int | None = None) -> bytes:
    """An answer, with the planted encoding defects applied."""
    defect = choices.defect
    if defect == "swapped-error":
        error = ((error & 0xFF) << 8) | (error >> 8)
    return udp_defects.tcp_check(defect, wire.encode(
        action, error, value,
        version=0x0100 if defect == "swapped-version" else wire.VERSION,
        transfer=wire.ROBOT_TO_BOX if defect == "wrong-transfer-type" else wire.BOX_TO_ROBOT,
        first_index=int(choices.first_index),
    ))


def decide(choices: Choices, event: Event, cycle: Cycle, conn: systematic.ConnState | None = None) -> Reply:
    """The box's reaction to one framer event (``conn``: what its connection remembers, for the
    systematic defects of :mod:`.systematic`)."""
    if choices.defect in systematic.SYSTEMATIC:
        reply: Reply = systematic.decide(choices, event, cycle, conn, _decide, answer)
        return reply
    return _decide(choices, event, cycle)


def _decide(choices: Choices, event: Event, cycle: Cycle) -> Reply:
    if isinstance(event, Close):
        return CLOSE
    if isinstance(event, Garbage):
        return HANG if choices.defect == "no-resync" else SILENT
    header = event.header
    if wire.not_a_request(header, choices.has_extension):
        return _not_request(choices, header)
    if isinstance(event, Rejected):  # a request header the framer would not take: B5 / implausible length
        return _malformed(choices, header)
    assert isinstance(event, Frame)
    if wire.request_ok(event.data, header, choices.check) and not udp_defects.refuses_check(choices.defect, event.data):
        return _well_formed(choices, header, event.data, cycle)
    if choices.defect == "zero-to-malformed" and header.action in (wire.POSE, wire.REG_POSE):
        return Reply(answer(choices, header.action))
    return _malformed(choices, header)


def _not_request(choices: Choices, header: Header) -> Reply:
    if choices.defect == "no-resync":
        return HANG
    how, echo = choices.not_request, choices.refusal_action == "echo"
    if header.action in wire.EXT_ACTIONS and header.is_request_start() and header.transfer == wire.ROBOT_TO_BOX:
        how, echo = choices.ext_refusal, choices.ext_refusal == "error-echo"  # 26/27 without the extension
    if how == "close":
        return CLOSE
    if how.startswith("error") and header.start == 0xFEFE:
        return Reply(answer(choices, header.action if echo else 0, _ERRORS[choices.refusal_code]))
    return SILENT


def _malformed(choices: Choices, header: Header) -> Reply:
    action = header.action
    if action in (wire.POSE, wire.REG_POSE, wire.TOLERANCE):
        return Reply(answer(choices, action, _MALFORMED_CODE[action]))
    if action in (wire.NONE, wire.CYCLE_ON, wire.CYCLE_OFF):
        if choices.malformed_blockless == "close":
            return CLOSE
        if choices.malformed_blockless == "error":
            return Reply(answer(choices, action, _MALFORMED_CODE[action]))
    if action in wire.EXT_ACTIONS and choices.malformed_ext == "400":
        return Reply(answer(choices, action, 400, 400))
    return SILENT


def _cycle(choices: Choices, action: int, cycle: Cycle) -> Reply:
    with cycle.lock:
        if action == wire.CYCLE_OFF:
            error = _ERRORS[choices.cycle_off_idle] if not cycle.on else wire.OK
            cycle.on = False
            return Reply(answer(choices, action, error))
        if choices.cycle_on_ready == "first-not-ready" and cycle.ready:
            cycle.ready = False
            return Reply(answer(choices, action, wire.NOT_READY))
        error = _ERRORS[choices.cycle_on_twice] if cycle.on else wire.OK
        cycle.on = True
    delay = 6.0 if choices.defect == "late-cycle-on" else 0.6 * choices.time_out * (choices.cycle_on_latency != "0")
    return Reply(answer(choices, action, error), delay=delay)


def _well_formed(choices: Choices, header: Header, frame: bytes, cycle: Cycle) -> Reply:
    action = header.action
    if choices.defect == "answers-some-actions" and action in (wire.TOLERANCE, wire.REG_POSE):
        return SILENT  # A1: read, and never answered
    if action in (wire.CYCLE_ON, wire.CYCLE_OFF):
        return _cycle(choices, action, cycle)
    if action == wire.PROG_IDX:
        value = int.from_bytes(frame[wire.HEADER_LEN + 1 : wire.HEADER_LEN + 5], "big", signed=True)
        if choices.prog_idx == "409":
            if choices.progidx_conflict == "error-code":
                return Reply(answer(choices, action, 409, value))
            return Reply(answer(choices, action, wire.OK, 409))
        return Reply(answer(choices, action, wire.OK, value))
    if action == wire.RESULT:
        return Reply(answer(choices, action, wire.OK, int(choices.vision_result)))
    return Reply(answer(choices, action))


def decide_datagram(choices: Choices, data: bytes, cycle: Cycle) -> list[bytes]:
    """R7/F7 over UDP: one frame per datagram with a CRC-16/MODBUS; bad datagrams are dropped (the answers, one
    datagram each; the UDP defects of :mod:`.udp_defects` change what is checked, taken and signed)."""
    out = []
    for frame in udp_defects.frames_of(choices.defect, data):
        header = Header.parse(frame)
        tcp_like = frame[:-2] + b"\0\0"
        reply = decide(replace(choices, tcp_check="ignore"), Frame(tcp_like, header), cycle)
        if reply.data:
            out.append(udp_defects.sign(choices.defect, reply.data))
    return out

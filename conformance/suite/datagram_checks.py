"""Helpers of the UDP cases (conformance/cases/udp_datagrams.py): datagram bytes, header fields, CRC matches, bad datagrams and the probe."""

from __future__ import annotations

import time

from ..harness.client import Answer, Closed, Malformed, Outcome, Silence, UdpChannel
from ..protocol import (
    Action,
    Frame,
    Transport,
    crc16_names,
    crc_function,
    encode,
    peek_action,
    pose_blocks,
    request,
)
from .case_context import CaseContext
from .case_judge import Inconclusive

POSE = (500.0, -20.0, 300.0, 180.0, 0.0, 90.0)

#: sessions whose UDP target answered no valid datagram (R7 cases end at once)
UDP_MUTE: dict[int, str] = {}


def udp_bytes(isight: CaseContext, frame: Frame) -> bytes:
    return encode(frame, isight.profile, Transport.UDP)


def pose_request(isight: CaseContext, action: Action = Action.POSE) -> Frame:
    return request(action, pose_blocks([POSE], isight.profile.first_index))


def action_of(outcome: Outcome) -> int | None:
    return peek_action(outcome.raw)


def crc_matches(body: bytes, check: bytes) -> list[str]:
    """Every (crcmod algorithm, byte order) whose CRC of ``body`` is ``check``."""
    out = []
    for name in crc16_names():
        value = crc_function(name)(body)
        for order in ("big", "little"):
            if value.to_bytes(2, order) == check:
                out.append(f"--crc={name} --crc-byte-order={order}")
    return out


def valid_requests(isight: CaseContext) -> list[tuple[str, Frame]]:
    return [("NONE", request(Action.NONE)), ("POSE", pose_request(isight))]


def bad_datagram(isight: CaseContext, kind: str) -> bytes:
    good = udp_bytes(isight, pose_request(isight))
    if kind == "wrong-crc":
        return good[:-2] + bytes([good[-2] ^ 0x5A, good[-1] ^ 0xA5])
    if kind == "truncated":
        return good[:-6]
    if kind == "trailing-bytes":
        return good + b"\x00\x00"
    if kind == "two-frames":
        return good + udp_bytes(isight, pose_request(isight, Action.REGISTER_POSE))
    raise ValueError(kind)


def is_probe(outcome: Outcome) -> bool:
    return isinstance(outcome, (Answer, Malformed)) and action_of(outcome) == Action.NONE


def await_probe(isight: CaseContext, ch: UdpChannel, start: float) -> tuple[list[Outcome], Outcome | None]:
    """Datagrams received until the probe's answer (bounded by time_out), then ``settle`` for late extras."""
    extras: list[Outcome] = []
    probe: Outcome | None = None
    deadline = start + isight.time_out_s
    while probe is None:
        remaining = deadline - time.monotonic()
        outcome = ch.next_outcome(max(0.0, remaining), since=start)
        if isinstance(outcome, Silence):
            break
        if isinstance(outcome, Closed):
            raise Inconclusive(f"the UDP target {ch.target} refused datagrams (ICMP port unreachable)")
        if is_probe(outcome):
            probe = outcome
        else:
            extras.append(outcome)
    if probe is not None:
        while True:
            outcome = ch.next_outcome(isight.settings.settle_s)
            if isinstance(outcome, (Silence, Closed)):
                break
            extras.append(outcome)
    return extras, probe


def require_udp_answers(isight: CaseContext, ch: UdpChannel) -> bytes:
    """A valid NONE datagram is answered (else R7 cannot be judged); returns the probe bytes."""
    probe = udp_bytes(isight, request(Action.NONE))
    mute = UDP_MUTE.get(id(isight.session))
    if mute:
        raise Inconclusive(mute)
    _extras, answer = await_probe(isight, ch, send_datagram(ch, probe, "NONE datagram: the box answers valid datagrams?"))
    if answer is None:
        UDP_MUTE[id(isight.session)] = reason = (
            f"the box answered no valid NONE datagram within time_out ({isight.time_out_s * 1000:.0f} ms): R7 cannot "
            "be judged (F7-01 judges the silence)")
        raise Inconclusive(reason)
    return probe


def send_datagram(ch: UdpChannel, data: bytes, note: str) -> float:
    start = time.monotonic()
    ch.send(data, note)
    return start

"""F7 and R7: the UDP transport (one datagram, one frame, CRC-16 in the check field).

``isight.udp()`` SKIPs without a UDP target (with no --target the bundled box's UDP
port is used). The CRC algorithm and its byte order are the profile's (``--crc``,
``--crc-byte-order``); PROFILE-01 tells which ones a box appears to use.

Silence over UDP has no connection to bound it, so the R7 cases send the bad
datagram and then a valid NONE probe datagram: a box that handles datagrams in
order answers the bad one first, if at all; after the probe's answer the case
watches ``settle`` for late extras. Only a box that answers no valid datagram at
all costs a full time_out (and its R7 cases end INCONCLUSIVE: F7-01 judges it).
"""

from __future__ import annotations

import time
from typing import Any

import pytest

from conformance.protocol import (
    Action,
    Frame,
    Transport,
    crc16_names,
    crc_function,
    encode,
    peek_action,
    peek_header,
    request,
)
from conformance.protocol.constants import CHECK_LEN
from conformance.protocol.field_bytes import ByteChange, byte_changes
from conformance.suite import (
    Answer,
    CaseContext,
    Closed,
    Expect,
    Inconclusive,
    Level,
    Malformed,
    Outcome,
    Requirement,
    Silence,
    UdpChannel,
    answered_allowed,
    case,
)

# -- the family's helpers: Helpers of the UDP cases (conformance/cases/udp_datagrams.py): datagram bytes, header fields, CRC matches, bad datagrams and the probe.
POSE = (500.0, -20.0, 300.0, 180.0, 0.0, 90.0)

#: sessions whose UDP target answered no valid datagram (R7 cases end at once)
UDP_MUTE: dict[int, str] = {}


def udp_bytes(isight: CaseContext, frame: Frame) -> bytes:
    return encode(frame, isight.profile, Transport.UDP)


def pose_request(isight: CaseContext, action: Action = Action.POSE) -> Frame:
    return request(action, isight.codec.pose_blocks([POSE]))


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


# -- the cases

# -- F7 ------------------------------------------------------------------------------------


@case("F7-01", ["F7", "A1"], Level.MUST, "A UDP request with the correct CRC is answered",
      "a NONE and a pose datagram carrying the profile's CRC each get an answer datagram",
      checks={"": Requirement(("F7", "A1"), "a datagram with exactly one frame and the correct CRC is answered (if the box "
                              "uses another CRC or byte order, PROFILE-01 tells which)",
                              accept=Expect("answered within time_out", lambda o: not isinstance(o, Silence)),
                              inconclusive=Expect("refused (ICMP port unreachable)", lambda o: isinstance(o, Closed)),
                              inconclusive_text="the UDP target refused the datagram (ICMP port unreachable)")})
def test_udp_request_answered(isight: CaseContext) -> None:
    ch = isight.udp()
    for name, frame in valid_requests(isight):
        data = udp_bytes(isight, frame)
        outcome = ch.request(data, f"{name} datagram with {isight.profile.crc} CRC ({isight.profile.crc_byte_order})")
        isight.judge(outcome, sent=data)
        if isinstance(outcome, Answer):
            isight.latencies_ms.append(outcome.latency_s * 1000)


@case("F7-02", ["F7"], Level.MUST, "UDP answers are one frame with the profile's CRC",
      "every answer datagram is exactly 12+N×L+2 bytes and its check field is the CRC-16 of bytes 0..12+N×L-1 "
      "under the profile's algorithm and byte order",
      checks={"header": Requirement(("F7",), "a datagram carries exactly one frame"),
              "length": Requirement(("F7",), "one datagram carries exactly one frame (12+N×L+2 bytes)"),
              "crc": Requirement(("F7",), "the check field is the CRC-16 ({crc}, {order}-endian) of the frame")})
def test_udp_answer_crc(isight: CaseContext) -> None:
    ch = isight.udp()
    profile = isight.profile
    judged = 0
    for name, frame in valid_requests(isight):
        data = udp_bytes(isight, frame)
        outcome = ch.request(data, f"{name} datagram")
        raw = outcome.raw
        if not raw:
            continue
        judged += 1
        head = peek_header(raw, 0, profile.byte_order)
        if head is None:
            raise isight.broken("header", expected="at least a 12-byte header", observed=f"{len(raw)} bytes", sent=data,
                                received=raw)
        end = head.frame_length - CHECK_LEN
        if len(raw) != end + 2:
            raise isight.broken("length", expected=f"{end + 2} bytes (N={head.block_count}, L={head.block_length})",
                                observed=f"{len(raw)} bytes", sent=data, received=raw)
        want = profile.check_bytes(raw[:end])
        if raw[end:] != want:
            seen = crc_matches(raw[:end], raw[end:])
            hint = f"; it matches {' or '.join(seen)}" if seen else "; it matches no crcmod 16-bit algorithm"
            raise isight.broken("crc", expected=want.hex(" "), observed=raw[end:].hex(" ") + hint, sent=data,
                                received=raw, crc=profile.crc, order=profile.crc_byte_order)
    if not judged:
        raise Inconclusive("the box answered no UDP request: nothing to judge (F7-01 judges the silence)")


@case("F7-03", ["F7", "A4"], Level.MUST, "NONE over UDP is answered NONE 0000",
      "the answer datagram echoes action 00 with error 0000",
      checks={"": Requirement(("A4",), "action 00 is answered with action 00 and 0000 (over UDP)",
                              accept=answered_allowed(Action.NONE))})
def test_udp_none(isight: CaseContext) -> None:
    ch = isight.udp()
    data = udp_bytes(isight, request(Action.NONE))
    isight.judge(ch.request(data, "NONE datagram"), sent=data)


@case("F7-04", ["F7", "A2", "S3"], Level.MUST, "Poses and tolerances over UDP are answered 0000 with no blocks",
      "23, 24 and 25 datagrams are each answered with their action, error 0000, no blocks",
      checks={"": Requirement(("A2", "S3"), "a well-formed {action.name} is answered 0000 with no blocks (over UDP)",
                              accept=lambda action, **_: answered_allowed(action))})
def test_udp_pose_answers(isight: CaseContext) -> None:
    ch = isight.udp()
    for frame in (pose_request(isight), pose_request(isight, Action.REGISTER_POSE),
                  request(Action.TOLERANCE, isight.codec.tolerance_blocks([0.25]))):
        data = udp_bytes(isight, frame)
        outcome = ch.request(data, f"{frame.action.name} datagram")
        isight.judge(outcome, sent=data, action=frame.action)
        assert isinstance(outcome, Answer)
        isight.latencies_ms.append(outcome.latency_s * 1000)


# -- R7 ------------------------------------------------------------------------------------


@pytest.mark.parametrize("kind", ["wrong-crc", "truncated", "trailing-bytes", "two-frames", "truncated-after-whole"])
@case("R7-01", ["R7", "R1", "F7"], Level.MUST, "A bad datagram is never answered 0000 and is dropped silently",
      "a datagram with a wrong CRC or not exactly one frame long is never answered 0000 (MUST) and gets no "
      "answer at all (SHOULD: an answer with a non-zero error is NON-STRICT); truncated-after-whole: the same pose "
      "datagram whole (answered 0000), then short of its last 3 bytes (a box that reuses its receive buffer and "
      "checks only that a datagram is not longer than its frame completes it with the previous datagram's bytes)",
      checks={"no-0000": Requirement(("R7",), "a datagram with a wrong CRC or not exactly one frame MUST NOT be answered 0000"),
              "dropped": Requirement(("R7",), "a datagram with a wrong CRC or not exactly one frame SHOULD be dropped "
                                     "silently", level=Level.SHOULD)})
def test_udp_bad_datagram(isight: CaseContext, kind: str) -> None:
    if kind == "truncated-after-whole":
        whole = udp_bytes(isight, pose_request(isight))
        judge_bad_datagram(isight, whole[:-3], "bad datagram: the pose datagram just sent whole, without its last "
                           "3 bytes", before=whole)
        return
    judge_bad_datagram(isight, bad_datagram(isight, kind), f"bad datagram: pose {kind}")


#: F7-05: each byte of the check field XORed on its own (the frame layout's table, protocol/field_bytes.py)
CHECK_CHANGES = byte_changes("check")


@pytest.mark.parametrize("change", CHECK_CHANGES, ids=[f"check-byte{c.byte}-x{c.mask:02x}" for c in CHECK_CHANGES])
@case("F7-05", ["F7", "R7", "R1"], Level.MUST, "Each byte of the UDP check field, changed on its own, makes the "
      "datagram invalid",
      "a pose datagram with one byte of its CRC changed (XOR 01 or FF), every other byte valid, is never answered "
      "0000 (MUST) and gets no answer at all (SHOULD: an answer with a non-zero error is NON-STRICT); a box that "
      "checks only one byte of the CRC answers it",
      checks={"no-0000": Requirement(("F7", "R7"), "a datagram whose CRC has {where} changed MUST NOT be answered "
                                     "0000"),
              "dropped": Requirement(("R7",), "a datagram whose CRC has {where} changed SHOULD be dropped silently",
                                     level=Level.SHOULD)})
def test_udp_each_check_byte(isight: CaseContext, change: ByteChange) -> None:
    bad = change.apply(udp_bytes(isight, pose_request(isight)))
    where = f"byte {change.byte} (XOR {change.mask:02x})"
    judge_bad_datagram(isight, bad, f"bad datagram: pose whose CRC has {where} changed", where=where)


def judge_bad_datagram(isight: CaseContext, bad: bytes, note: str, before: bytes = b"", **values: Any) -> None:
    """R7: (``before``, a valid datagram, and its answer,) ``bad``, then a valid NONE probe datagram; never
    answered 0000 (MUST), no answer at all (SHOULD)."""
    ch = isight.udp()
    probe = require_udp_answers(isight, ch)
    if before:
        ch.send(before, "a valid datagram first (its answer is awaited): what a reused receive buffer keeps")
        ch.send(probe, "probe: a valid NONE datagram; its answer bounds the wait")
        await_probe(isight, ch, time.monotonic())
    isight.last_sent = bad
    start = send_datagram(ch, bad, note)
    ch.send(probe, "probe: a valid NONE datagram; its answer bounds the wait")
    extras, answer = await_probe(isight, ch, start)
    replies = [o for o in extras if isinstance(o, (Answer, Malformed))]
    isight.details["replies_to_bad"] = [o.raw.hex(" ") for o in replies]
    if answer is None:
        isight.details["probe"] = "not answered within time_out"
    ok = [o for o in replies if getattr(peek_header(o.raw, 0, isight.profile.byte_order), "error_code", None) == 0]
    if ok:
        raise isight.broken("no-0000", expected="silence (or a non-zero error)",
                            observed=f"{len(replies)} answer(s), {ok[0].describe()}", sent=bad, received=ok[0].raw,
                            **values)
    if replies:
        raise isight.broken("dropped", expected="silence", observed="; ".join(o.describe() for o in replies), sent=bad,
                            received=replies[0].raw, **values)

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

import pytest

from conformance.harness.client import Answer, Closed, Malformed, Silence
from conformance.protocol import (
    Action,
    peek_header,
    request,
    tolerance_blocks,
)
from conformance.protocol.constants import CHECK_LEN
from conformance.suite import CaseContext, Expect, Inconclusive, Level, Requirement, answered_allowed, case
from conformance.suite.datagram_checks import (
    await_probe,
    bad_datagram,
    crc_matches,
    pose_request,
    require_udp_answers,
    send_datagram,
    udp_bytes,
    valid_requests,
)

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
    first = isight.profile.first_index
    for frame in (pose_request(isight), pose_request(isight, Action.REGISTER_POSE),
                  request(Action.TOLERANCE, tolerance_blocks([0.25], first))):
        data = udp_bytes(isight, frame)
        outcome = ch.request(data, f"{frame.action.name} datagram")
        isight.judge(outcome, sent=data, action=frame.action)
        assert isinstance(outcome, Answer)
        isight.latencies_ms.append(outcome.latency_s * 1000)


# -- R7 ------------------------------------------------------------------------------------


@pytest.mark.parametrize("kind", ["wrong-crc", "truncated", "trailing-bytes", "two-frames"])
@case("R7-01", ["R7", "R1", "F7"], Level.MUST, "A bad datagram is never answered 0000 and is dropped silently",
      "a datagram with a wrong CRC or not exactly one frame long is never answered 0000 (MUST) and gets no "
      "answer at all (SHOULD: an answer with a non-zero error is NON-STRICT)",
      checks={"no-0000": Requirement(("R7",), "a datagram with a wrong CRC or not exactly one frame MUST NOT be answered 0000"),
              "dropped": Requirement(("R7",), "a datagram with a wrong CRC or not exactly one frame SHOULD be dropped "
                                     "silently", level=Level.SHOULD)})
def test_udp_bad_datagram(isight: CaseContext, kind: str) -> None:
    ch = isight.udp()
    probe = require_udp_answers(isight, ch)
    bad = bad_datagram(isight, kind)
    isight.last_sent = bad
    start = send_datagram(ch, bad, f"bad datagram: pose {kind}")
    ch.send(probe, "probe: a valid NONE datagram; its answer bounds the wait")
    extras, answer = await_probe(isight, ch, start)
    replies = [o for o in extras if isinstance(o, (Answer, Malformed))]
    isight.details["replies_to_bad"] = [o.raw.hex(" ") for o in replies]
    if answer is None:
        isight.details["probe"] = "not answered within time_out"
    ok = [o for o in replies if getattr(peek_header(o.raw, 0, isight.profile.byte_order), "error_code", None) == 0]
    if ok:
        raise isight.broken("no-0000", expected="silence (or a non-zero error)",
                            observed=f"{len(replies)} answer(s), {ok[0].describe()}", sent=bad, received=ok[0].raw)
    if replies:
        raise isight.broken("dropped", expected="silence", observed="; ".join(o.describe() for o in replies), sent=bad,
                            received=replies[0].raw)

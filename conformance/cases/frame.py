"""F: the frame (start word, version, direction, byte order, length, check fields).

F4-02 changes each byte of each multi-byte header field on its own (``protocol/field_bytes.py``
derives the changes from the frame layout): the start word, the version and the block length of a
valid one-pose request, every other byte kept. A block length made longer is followed by zero bytes
up to the frame it announces, so a box that reads the whole field waits for nothing that never
comes, and one that reads only its low byte (L = 0x0119 taken as 25) answers the 39 bytes 0000.
The error code is left out: a request's error field is undefined, and a box may accept or refuse a
non-zero one (``protocol/legal.py``, request-error-field), so no verdict follows from it. The check
field's bytes matter only over UDP (F7-05, ``udp_datagrams.py``); over TCP a receiver SHOULD ignore
it (F6).
"""

from __future__ import annotations

import pytest

from conformance.protocol import (
    DEFAULT_PROFILE,
    Action,
    Frame,
    Header,
    Transport,
    codec_for,
    encode,
    encode_raw,
    header_field_bytes,
    request,
)
from conformance.protocol.constants import START_BYTES
from conformance.protocol.field_bytes import ByteChange, byte_changes, completed
from conformance.suite import (
    ANSWERED,
    ANSWERED_0,
    NOT_0000,
    NOT_OK,
    Answer,
    CaseContext,
    Level,
    Malformed,
    Requirement,
    answered,
    answered_allowed,
    case,
)

# -- the family's helpers: Helpers of the F cases (conformance/cases/frame.py): the pose request and an answer's bytes.
POSE_VALUES = (500.0, 0.0, 300.0, 180.0, 0.0, 90.0)


def pose_request(isight: CaseContext) -> Frame:
    """A one-pose request, its block indexed from the profile's first index (the codec applies it, B3)."""
    return request(Action.POSE, isight.codec.pose_blocks([POSE_VALUES]))


def answer_bytes(isight: CaseContext, action: Action = Action.NONE) -> tuple[Answer, bytes]:
    outcome = isight.exchange(request(action), f"{action.name} request")
    isight.judge(outcome, "answered", sent=b"", action=action)
    assert isinstance(outcome, Answer)
    return outcome, outcome.raw


#: F4-02's fields: the multi-byte header fields whose change makes a request invalid (not the error code: see above)
CHANGED_FIELDS = ("start_word", "version", "block_length")
HEADER_CHANGES = byte_changes(*CHANGED_FIELDS)


#: the one-pose request's header (its fields do not depend on the first index, which only the blocks carry)
POSE_HEADER = request(Action.POSE, codec_for(DEFAULT_PROFILE).pose_blocks([POSE_VALUES])).header


def valid_value(change: ByteChange) -> int:
    """The changed field's value in the valid one-pose request (the same under either byte order)."""
    return int(getattr(POSE_HEADER, change.field))


def change_id(change: ByteChange) -> str:
    """E.g. ``block-length-0119``: the field and the value it reads after the change."""
    return f"{change.field.replace('_', '-')}-{change.value(valid_value(change)):04x}"


# -- the cases

@case("F1-01", ["F1"], Level.MUST, "Answers start with FE FE", "every answer's first two bytes are fe fe",
      checks={"answered": ANSWERED_0, "": Requirement(("F1",), "the start word is FE FE")}, shares_box=True)
def test_answer_start_word(isight: CaseContext) -> None:
    _, raw = answer_bytes(isight)
    got = header_field_bytes(raw, "start_word")
    if got != START_BYTES:
        raise isight.broken(expected="fe fe", observed=got.hex(" "), received=raw)


@case("F1-02", ["F1", "A5", "R1"], Level.MUST, "A frame with a wrong start word is not answered 0000",
      "silence, a non-zero error, or a close; never 0000",
      checks={"": Requirement(("A5",), f"a frame that is not a request {NOT_0000}", accept=NOT_OK)}, shares_box=True)
def test_wrong_start_word(isight: CaseContext) -> None:
    bad = bytearray(encode(pose_request(isight), isight.profile))
    bad[0:2] = b"\xfe\xff"
    isight.judge(isight.send_malformed(bytes(bad), "pose with start word fe ff"))


@case("F2-01", ["F2"], Level.MUST, "Answers carry version 00 01", "bytes 2-3 of every answer are 00 01",
      checks={"answered": ANSWERED_0, "": Requirement(("F2",), "the version is 00 01")}, shares_box=True)
def test_answer_version(isight: CaseContext) -> None:
    _, raw = answer_bytes(isight)
    got = header_field_bytes(raw, "version")
    if got != b"\x00\x01":
        raise isight.broken(expected="00 01", observed=got.hex(" "), received=raw)


@case("F2-02", ["F2", "A5", "R1"], Level.MUST, "A frame with version 00 02 is not answered 0000",
      "silence, a non-zero error, or a close; never 0000",
      checks={"": Requirement(("A5",), f"a frame with version ≠ 00 01 {NOT_0000}", accept=NOT_OK)}, shares_box=True)
def test_wrong_version(isight: CaseContext) -> None:
    bad = encode_raw(Header(version=0x0002, action=Action.NONE))
    isight.judge(isight.send_malformed(bad, "NONE request with version 00 02"))


@case("F3-01", ["F3"], Level.MUST, "Answers carry transfer type 10", "byte 4 of every answer is 10",
      checks={"answered": ANSWERED, "": Requirement(("F3",), "box→robot frames carry transfer type 10")},
      shares_box=True)
def test_answer_transfer_type(isight: CaseContext) -> None:
    for action in (Action.NONE, Action.POSE):
        outcome = isight.exchange(request(action) if action is Action.NONE else pose_request(isight), f"{action.name} request")
        header = outcome.error.header if isinstance(outcome, Malformed) else None
        if isinstance(outcome, Malformed) and header is not None and header.transfer_type != 0x10:  # F3 first
            raise isight.broken(expected="10", observed=f"{header.transfer_type:02x}", received=outcome.error.raw)
        isight.judge(outcome, "answered", action=action)


@case("F3-02", ["F3", "A5", "R1"], Level.MUST, "A request with transfer type 10 (box→robot) is not answered 0000",
      "silence, a non-zero error, or a close; never 0000",
      checks={"": Requirement(("A5",), f"transfer type ≠ 01 is not a request and {NOT_0000}", accept=NOT_OK)})
def test_request_with_box_direction(isight: CaseContext) -> None:
    bad = encode_raw(Header(transfer_type=0x10, action=Action.CYCLE_ON))
    isight.judge(isight.send_malformed(bad, "CycleOn with transfer type 10"))


@case("F5-01", ["F5", "A2"], Level.MUST, "An answer is exactly 12 + N×L + 2 bytes",
      "the NONE answer is 14 bytes and nothing else follows",
      checks={"none": Requirement(("A4",), "NONE is answered 0000", accept=answered_allowed(Action.NONE)),
              "": Requirement(("F5", "A1"), "one answer of exactly 12+N×L+2 bytes")}, shares_box=True)
def test_answer_length(isight: CaseContext) -> None:
    conn = isight.connect()
    isight.judge(conn.request(request(Action.NONE), "NONE request"), "none", sent=b"")
    trailing = conn.drain(isight.settings.settle_s)
    if trailing:
        raise isight.broken(expected="nothing after the answer", observed="; ".join(o.describe() for o in trailing),
                            received=isight.transcript.received())


@case("F6-01", ["F6"], Level.MUST, "Over TCP the box sends check 00 00", "the last two bytes of every answer are 00 00",
      checks={"answered": Requirement(("A1",), "{action.name} is answered", accept=lambda action, **_: answered(action)),
              "": Requirement(("F6",), "a TCP sender MUST send check 00 00")})
def test_tcp_check_zero(isight: CaseContext) -> None:
    conn = isight.connect()
    for action, frame in ((Action.NONE, request(Action.NONE)), (Action.POSE, pose_request(isight)), (Action.CYCLE_OFF, request(Action.CYCLE_OFF))):
        outcome = conn.request(frame, f"{action.name} request")
        if isinstance(outcome, Answer) and outcome.raw[-2:] != b"\x00\x00":
            raise isight.broken(expected="00 00", observed=outcome.raw[-2:].hex(" "), received=outcome.raw)
        isight.judge(outcome, "answered", sent=b"", action=action)


@case("F6-02", ["F6"], Level.SHOULD, "A TCP receiver accepts a correct CRC in the check field",
      "the request with a CRC in its check field is answered like one with 00 00",
      checks={"": Requirement(("F6",), "a TCP receiver SHOULD ignore the check field (accept a correct CRC as well as 00 00)",
                              accept=answered_allowed(Action.POSE))}, shares_box=True)
def test_tcp_check_crc_accepted(isight: CaseContext) -> None:
    # indexed from the profile's first index: a box taking 01 first refuses a block indexed 00 (B3), not the CRC
    frame = request(Action.POSE, isight.codec.pose_blocks([(1.0, 2.0, 3.0, 4.0, 5.0, 6.0)]))
    data = encode(frame, isight.profile, Transport.UDP)  # same bytes, CRC in the check field
    isight.judge(isight.exchange(data, "pose request whose check field holds its CRC"), sent=b"")


@case("F4-02", ["F4", "F1", "F2", "F5", "A5", "R1"], Level.MUST,
      "Each byte of each multi-byte header field, changed on its own, makes the request invalid",
      "a one-pose request with one byte of its start word, version or block length changed (XOR 01 or FF), every "
      "other byte valid, is never answered 0000: silence, a non-zero error or a close (a box reading only one byte "
      "of a field, e.g. L = 0x0119 taken as 25, answers 0000); a longer L is followed by zero bytes up to the "
      "frame it announces. The error code is not changed: a request's error field is undefined (a box may accept "
      "or refuse a non-zero one)",
      checks={"start_word": Requirement(("F4", "F1", "A5"), "a frame whose start word reads {value:04X} is not a request "
                                        f"and {NOT_0000}", accept=NOT_OK),
              "version": Requirement(("F4", "F2", "A5"), f"a frame whose version reads {{value:04X}} {NOT_0000}",
                                     accept=NOT_OK),
              "block_length": Requirement(("F4", "F5", "B1", "R1"), "a pose request whose block length reads {value:04X} "
                                          "(its one block is 25 bytes) is a parse error and MUST NOT be answered 0000",
                                          accept=NOT_OK)}, shares_box=True)
@pytest.mark.parametrize("change", HEADER_CHANGES, ids=[change_id(c) for c in HEADER_CHANGES])
def test_each_byte_of_each_field(isight: CaseContext, change: ByteChange) -> None:
    bad = change.apply(encode(pose_request(isight), isight.profile), isight.profile.byte_order)
    bad = completed(bad, codec_for(isight.profile).frame_length(bad))  # a longer L: its frame sent whole
    valid = valid_value(change)
    outcome = isight.send_malformed(bad, f"pose request with {change.describe(valid)}")
    isight.judge(outcome, change.field, sent=bad, value=change.value(valid))

"""Profile discovery (PROFILE-01) and F4, the byte order of the box's answers.

PROFILE-01 never judges: it tells which reading of each **[decision]** the box
appears to use and prints the flags to rerun the suite with:

* F4 header byte order: a NONE request with big-endian and with little-endian
  header fields (the version field is the difference: 00 01 / 01 00), which one is
  answered 0000;
* B3 first block index: a one-pose request with index 0 and with index 1, which
  one is answered 0000;
* F7 UDP CRC: a NONE datagram with the CRC of every crcmod 16-bit algorithm in both
  byte orders (common ones first, a short wait per try, stop at the first that is
  answered 0000, confirmed by sending it again); it counts only when a datagram with a
  check no algorithm computes is refused (a box that answers any check shows no CRC).

Every reading rests on positive evidence: the one reading answered 0000 where the other
is not. A reading no answer singles out (both answered, neither, no UDP target) is
reported as not determined, the profile's kept as a guess, never as "the profile fits".

Every TCP try is bounded by an in-order probe (answers come in order, A1), so a box
that stays silent to the wrong reading costs nothing but the probe's round trip.
"""

from __future__ import annotations

from conformance.protocol import (
    Action,
    BlockType,
    Frame,
    PoseBlock,
    TransferType,
    encode,
    header_field_bytes,
    peek_header,
    request,
    value_blocks,
)
from conformance.suite import CaseContext, Inconclusive, Level, Requirement, Sig, Signature, case
from conformance.suite.profile_discovery import (
    POSE,
    answers_other_order_only,
    discover_profile,
)


@case("PROFILE-01", ["B3", "F7", "F4"], Level.MAY, "Profile discovery: first index, UDP CRC, header byte order",
      "INFORMATIONAL: which first block index, UDP CRC algorithm and byte order, and header byte order the box "
      "answers 0000, and the flags to rerun the suite with", needs=("any-profile",))
def test_profile_discovery(isight: CaseContext) -> None:
    discover_profile(isight)


# -- F4 --------------------------------------------------------------------------------------


@case("F4-01", ["F4"], Level.MUST, "Answers' multi-byte fields are in the profile's byte order (big-endian)",
      "the version reads 00 01, the error code of an answer to a malformed pose reads 10 01 (not 01 10), the "
      "block length of a ProgIdx answer reads 00 05 (extension only); little-endian under --byte-order=little",
      checks={"header-order": Requirement(("F4",), "multi-byte header fields are {order}-endian"),
              "": Requirement(("F4",), "multi-byte fields are {order}-endian ({what})")})
def test_answer_byte_order(isight: CaseContext) -> None:
    order = isight.profile.byte_order
    judged: list[str] = []

    def expect(raw: bytes, field: str, value: int, what: str, sent: bytes) -> None:
        want = value.to_bytes(2, order)  # type: ignore[arg-type]
        got = header_field_bytes(raw, field)
        if got == want:
            judged.append(what)
            return
        if got != want[::-1]:
            isight.details.setdefault("not_judged", []).append(f"{what}: read {got.hex(' ')} (not F4's business)")
            return
        # the same defect as every other case sees in those answers: group them under one root cause
        signature = {"version": Signature(Sig.ANSWER, clause="F2", field="version", value=got.hex()),
                     "error_code": Signature(Sig.SWAPPED, "error-code")}.get(field)
        raise isight.broken(expected=want.hex(" "), observed=f"{got.hex(' ')}: {what} in the other byte order",
                            sent=sent, received=raw, signature=signature, order=order, what=what)

    conn = isight.connect()
    sent = encode(request(Action.NONE), isight.profile)
    raw = conn.request(sent, "NONE request").raw
    if len(raw) < 12:
        answers_other_order_only(isight, sent)
    expect(raw, "version", 1, "version 00 01", sent)
    first = isight.profile.first_index
    gap = Frame(TransferType.ROBOT_TO_BOX, Action.POSE, (PoseBlock(first, POSE), PoseBlock(first + 2, POSE)))
    bad = encode(gap, isight.profile)
    raw = isight.send_malformed(bad, "two poses with indexes first, first+2 (B3 gap): answered 1001?").raw
    if header_field_bytes(raw, "error_code") in (b"\x10\x01", b"\x01\x10"):
        expect(raw, "error_code", 0x1001, "error code 1001", bad)
    if isight.session.detect_extension(isight.transcript):
        sent = encode(request(Action.PROG_IDX, value_blocks([5], first)), isight.profile)
        conn = isight.connect()
        conn.request(sent, "ProgIdx 5: block length reads 5?")
        raw = isight.transcript.received(conn.conn_id)  # the wire bytes: a swapped L would derail the decoder
        if getattr(peek_header(raw), "block_type", None) == BlockType.VALUE:
            expect(raw, "block_length", 5, "block length 5", sent)
    isight.details["checked"] = judged
    if not judged:
        raise Inconclusive("the box sent no answer whose multi-byte fields could be read")

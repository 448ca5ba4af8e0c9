"""The answer-field and field-acceptance experiments of the diagnose phase against boxes of tests/impls served in
this process (sockets and threads, no suite run): the one field isolated, named in the title, and confirmed."""

from __future__ import annotations

from conformance.diagnose.block_length import with_length
from conformance.diagnose.phase import diagnose
from conformance.engine.rootcause import SessionFacts
from conformance.harness.target import Target
from conformance.model.verdicts import CaseResult, Level, RootCause, Verdict
from conformance.protocol import Profile
from tests.impls.box import start_box, variant

POSE_HEAD = "fefe0001012301010019000000"


def _case(case_id: str, sent: bytes, received: str) -> CaseResult:
    return CaseResult(case_id, case_id, ("A3",), Level.MUST, Verdict.FAIL, "seen", sent_hex=sent.hex(),
                      received_hex=received)


def _diagnosed(name: str, kind: str, cases: list[CaseResult]) -> RootCause:
    choices = variant(name).choices
    profile = Profile().replace(first_index=int(choices.first_index), time_out_ms=2000)
    cause = RootCause("RC1", ("A3",), "as the catalogue read it", "evidence", [c.id for c in cases], kind=kind)
    box = start_box(name)
    try:
        done = diagnose([cause], cases, SessionFacts(), Target("127.0.0.1", box.port), profile, 2.0)
    finally:
        box.stop()
    return done.causes[0]


def test_swapped_error_codes_and_a_block_length_read_from_its_low_byte_are_isolated_and_confirmed() -> None:
    first = int(variant("swapped-error").choices.first_index)
    pose = bytes.fromhex(POSE_HEAD[:-2] + f"{first:02x}") + bytes(24) + bytes(2)
    swapped = _diagnosed("swapped-error", "byte-order", [_case("A3-01", with_length(pose, 24),
                                                                 "fefe00011023000000000110" "0000")])
    assert swapped.confirmed is True and swapped.diagnosis is not None, swapped.title
    assert swapped.diagnosis["mechanism"] == "error-byte-order", swapped.title
    assert "error code" in swapped.title.lower() and "byte order" in swapped.title.lower()

    first = int(variant("low-byte-length").choices.first_index)
    pose = bytes.fromhex(POSE_HEAD[:-2] + f"{first:02x}") + bytes(24) + bytes(2)
    low = _diagnosed("low-byte-length", "wrong-code", [_case("F4-02", with_length(pose, 0x119),
                                                             "fefe00011023000000000000" "0000")])
    assert low.confirmed is True and low.diagnosis is not None, low.title
    assert low.diagnosis["mechanism"] == "block-length" and "low byte" in low.title, low.title

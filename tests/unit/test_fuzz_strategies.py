"""Fuzz strategies (conformance/fuzz/strategies.py): the clause each breaks, profiles, shrinking."""

from __future__ import annotations

import struct

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from hypothesis.errors import NoSuchExample

from conformance.fuzz.oracle import Rule
from conformance.fuzz.strategies import EDGE_FINITE_BITS, FuzzCase, Strategies
from conformance.protocol import (
    Action,
    Profile,
    ProtocolError,
    StreamDecoder,
    TransferType,
    Transport,
    decode_datagram,
    parse_frame,
)

FAST = settings(max_examples=60, deadline=None, database=None, suppress_health_check=list(HealthCheck))
PROFILES = [Profile(), Profile(first_index=1), Profile(byte_order="little", float_byte_order="little"),
            Profile(crc="xmodem", crc_byte_order="little")]
#: The clauses the codec may report first for each strategy (the strategy's own, or a more specific one).
FIRST_CLAUSE = {
    "F1-start-word": {"F1"}, "F2-version": {"F2"}, "F3-direction": {"F3"}, "A5-unknown-action": {"A5"},
    "B5-shape": {"B5", "B1", "B2", "E1", "E2", "E3"}, "B3-index": {"B3"}, "B4-non-finite": {"B4"},
    "F5-truncated": {"F5"}, "F6-check": {"F6", ""}, "R5-oversized": {"F5", "B5", "B1", "B2", "E1", "E2", "E3"},
    "F7-crc": {"F7"}, "F7-cut": {"F5"}, "F7-padded": {"F5"}, "F7-index": {"B3"},
}


def _find(strategy: st.SearchStrategy[FuzzCase], condition: object) -> FuzzCase:
    from hypothesis import find

    return find(strategy, condition, settings=settings(max_examples=2000, database=None, deadline=None,  # type: ignore[arg-type]
                                                        suppress_health_check=list(HealthCheck)))


@pytest.mark.parametrize("profile", PROFILES, ids=["default", "first-index-1", "little-endian", "xmodem-little"])
def test_every_case_breaks_the_clause_its_strategy_names(profile: Profile) -> None:
    s = Strategies(profile, extension=True, udp=True)

    @FAST
    @given(st.lists(s.cases(), min_size=1, max_size=8))
    def check(batch: list[FuzzCase]) -> None:
        for case in batch:
            assert case.expects, case
            allowed = FIRST_CLAUSE.get(case.kind)
            if allowed is not None:
                assert case.first_clause in allowed or (case.first_clause == case.clause and "" in allowed), case
            if case.kind in ("valid", "F7-valid", "B4-edge"):
                assert case.valid, case
                transport = case.transport
                frame = parse_frame(case.data, profile, transport, TransferType.ROBOT_TO_BOX)
                assert frame.is_request
                if frame.blocks:
                    assert frame.blocks[0].index == profile.first_index
            if case.transport is Transport.TCP and not case.eof:  # the probe will start on a frame boundary
                decoder = StreamDecoder(profile)
                decoder.feed(case.wire)
                assert decoder.buffered == 0, case

    check()


def test_udp_cases_only_with_a_udp_target_and_extension_actions_only_with_e() -> None:
    no_udp = Strategies(Profile(), extension=False, udp=False)
    assert "F7-udp" not in no_udp.categories()
    assert Action.PROG_IDX not in no_udp.actions

    @FAST
    @given(no_udp.cases())
    def check(case: FuzzCase) -> None:
        assert case.transport is Transport.TCP
        if case.kind == "valid":
            assert case.data[5] not in (0x26, 0x27)

    check()
    with pytest.raises(ValueError, match="unknown fuzz categories"):
        no_udp.cases(("nonsense",))


def test_malformed_cases_carry_their_oracle() -> None:
    s = Strategies(Profile())
    bad_index = _find(s.cases(("B3-index",)), lambda c: c.data[5] == Action.POSE)
    assert [e.rule for e in bad_index.expects] == [Rule.REJECT] and bad_index.expects[0].named_error == 0x1001
    tolerance = _find(s.cases(("B3-index",)), lambda c: c.data[5] == Action.TOLERANCE)
    assert tolerance.expects[0].named_error == 0x1002
    garbage = _find(s.cases(("F1-garbage",)), lambda c: True)
    assert garbage.expects[0].rule is Rule.NOT_REQUEST and garbage.expects[0].named_error is None
    nan = _find(s.cases(("B4-floats",)), lambda c: c.kind == "B4-non-finite")
    assert nan.expects[0].rule is Rule.REJECT_SHOULD
    lenient = Strategies(Profile(strict=False))
    assert _find(lenient.cases(("B4-floats",)), lambda c: c.kind == "B4-non-finite").expects[0].rule is Rule.ANY


def test_cases_shrink_to_the_smallest_readable_frame() -> None:
    s = Strategies(Profile(), extension=True)
    # the smallest malformed case: one zero byte of garbage, or a NONE request with start word 00 00
    assert _find(s.cases(), lambda c: not c.valid).data.hex() in ("00", "0000000101000000000000000000")
    # a wrong index: one pose block, index 1, all zeros
    assert _find(s.cases(("B3-index",)), lambda c: True).data.hex() == (
        "fefe00010123010100190000" + "01" + "00" * 24 + "0000")
    # the first index 1 profile: index 2 is the smallest wrong one
    assert _find(Strategies(Profile(first_index=1)).cases(("B3-index",)), lambda c: True).data[12] == 2
    # a valid request: NONE
    assert _find(s.cases(("valid",)), lambda c: True).data.hex() == "fefe000101000000000000000000"


def _words(data: bytes) -> list[int]:
    """The float32 words of a pose/tolerance request's blocks (big-endian)."""
    n, length = data[7], int.from_bytes(data[8:10], "big")
    return [struct.unpack_from(">I", data, 12 + i * length + 1 + 4 * k)[0]
            for i in range(n) for k in range((length - 1) // 4)]


def test_float_edge_values_and_nan_payloads_reach_the_wire() -> None:
    s = Strategies(Profile())
    edge = _find(s.cases(("B4-floats",)), lambda c: c.kind == "B4-edge")
    assert set(_words(edge.data)) & set(EDGE_FINITE_BITS)
    payload = _find(s.cases(("B4-floats",)), lambda c: any(
        (w & 0x7F800000) == 0x7F800000 and (w & 0x7FFFFF) not in (0, 0x400000, 1, 0x7FFFFF) for w in _words(c.data)))
    assert payload.kind == "B4-non-finite"


def test_truncation_ends_the_stream_and_a_cut_header_gets_filler() -> None:
    s = Strategies(Profile())
    truncated = _find(s.cases(("F5-truncated",)), lambda c: len(c.data) > 12)
    assert truncated.eof and not truncated.filler and truncated.expects[-1].clause == "F5"
    spliced = _find(s.cases(("F5-spliced",)), lambda c: bool(c.filler))
    assert not spliced.eof and set(spliced.filler) == {0}


def test_udp_cases_are_one_datagram_each() -> None:
    s = Strategies(Profile(crc="kermit"), udp=True)
    crc = _find(s.cases(("F7-udp",)), lambda c: c.kind == "F7-crc")
    with pytest.raises(ProtocolError) as err:
        decode_datagram(crc.data, Profile(crc="kermit"))
    assert err.value.clause == "F7" and crc.expects[0].rule is Rule.DROP
    valid = _find(s.cases(("F7-udp",)), lambda c: c.kind == "F7-valid" and c.data[5] == Action.POSE)
    assert decode_datagram(valid.data, Profile(crc="kermit")).action is Action.POSE
    with pytest.raises(NoSuchExample):
        _find(s.cases(("F7-udp",)), lambda c: c.transport is Transport.TCP)

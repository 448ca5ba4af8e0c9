"""Mutants of the drawn cases (pure): seeded, protocol-aware, never a header a trusting box would wait on."""

from __future__ import annotations

from conformance.fuzz.mutants import MAX_BODY, Mutants
from conformance.fuzz.strategies import Strategies
from conformance.protocol import BLOCK_LEN, HEADER_LEN, Action, BlockType, Header, Profile, Transport, parse_frame
from conformance.protocol.constants import TransferType


def parents(s: Strategies) -> list:  # type: ignore[type-arg]
    tol = Header(action=Action.TOLERANCE, block_type=BlockType.TOLERANCE, block_count=3, block_length=5)
    pose = Header(action=Action.POSE, block_type=BlockType.POSE, block_count=1, block_length=25)
    return [s.case("valid", "", s.raw(tol, s.blocks(BlockType.TOLERANCE, 3, bytes(12))), "tolerance ×3"),
            s.case("valid", "", s.raw(pose, s.blocks(BlockType.POSE, 1, bytes(24))), "pose ×1"),
            s.case("valid", "", s.raw(Header(action=Action.NONE)), "NONE")]


def run(seed: int, n: int = 400) -> list:  # type: ignore[type-arg]
    s = Strategies(Profile(), udp=True)
    m = Mutants(s, seed)
    for case in parents(s):
        m.feed(case)
    got = [m.next() for _ in range(n)]
    assert sum(x is None for x in got) < n // 20  # an operator that does not apply is rare after eight tries
    return [x for x in got if x is not None]


def test_the_same_seed_makes_the_same_mutants_and_another_seed_others():
    a, b, c = run(1), run(1), run(2)
    assert [x.wire for x in a] == [x.wire for x in b]
    assert [x.wire for x in a] != [x.wire for x in c]
    assert all(x.kind == "mutant" and "a mutant of a valid case" in x.note for x in a)


def test_no_mutant_announces_more_than_the_largest_frame():
    s = Strategies(Profile())
    for case in run(3, 1500):
        if len(case.data) >= HEADER_LEN:
            assert s.codec.parse_header(case.data).body_length <= MAX_BODY


def test_recounted_block_requests_are_well_formed_with_every_kind_of_count():
    counts = set()
    for case in run(4, 3000):
        if case.note.startswith("re-encoded with"):
            frame = parse_frame(case.data, Profile(), Transport.TCP, TransferType.ROBOT_TO_BOX)
            assert case.valid and frame.header.block_count == int(case.note.split()[2])
            assert frame.header.block_length == BLOCK_LEN[BlockType(frame.header.block_type)]
            counts.add(frame.header.block_count)
    assert 7 in counts and 255 in counts and len(counts) > 20


def test_a_udp_parent_gives_datagrams():
    s = Strategies(Profile(), udp=True)
    m = Mutants(s, 5)
    header = Header(action=Action.POSE, block_type=BlockType.POSE, block_count=1, block_length=25)
    m.feed(s.case("F7-udp", "F7", s.raw(header, s.blocks(BlockType.POSE, 1, bytes(24)), transport=Transport.UDP),
                  "datagram", Transport.UDP))
    got = [m.next() for _ in range(200)]
    assert all(c is not None and c.transport is Transport.UDP for c in got)
    assert not any(c.note.startswith(("followed by", "repeated")) for c in got if c is not None)  # one datagram each


def test_truncated_and_split_cases_are_not_parents():
    s = Strategies(Profile())
    m = Mutants(s, 6)
    import dataclasses

    case = parents(s)[1]
    m.feed(dataclasses.replace(case, eof=True))
    m.feed(dataclasses.replace(case, splits=(3,), gap_s=0.001))
    assert m.next() is None

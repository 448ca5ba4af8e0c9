"""The legal framings of bytes sent to a box (conformance/protocol/framings.py).

R6: a receiver that meets bad bytes may (a) trust a header whose start word and version
are right and skip its announced length, (b) reject the header and resume at the next
FE FE searching from any offset 1..12 after its first byte, or (c) close. The Reader must
offer every one of them, and nothing else; which one a box chose is explain.py's search
(tests/unit/test_explain.py). Bytes are built with the codec; no sockets.
"""

from __future__ import annotations

from typing import Any

import pytest
from hypothesis import given
from hypothesis import strategies as st

from conformance.protocol import Action, Header, Profile, answer, encode, encode_raw, pose_blocks, request
from conformance.protocol.answers import Cycle, Expectation, Finding, Rule
from conformance.protocol.framings import BAD, PENDING, VALID, End, Event, Explanation, Reader, embedded_actions
from conformance.protocol.levels import Level

P = Profile()
NONE = encode(request(Action.NONE))
POSE = encode(request(Action.POSE, pose_blocks([(1.0, 2.0, 3.0, 4.0, 5.0, 6.0)])))
POSE_HEADER = POSE[:12]  # announces one 25-byte pose block: 39 bytes in all
BAD_INDEX = encode(request(Action.POSE, pose_blocks([(0.0,) * 6], first_index=1)))  # B3
HALF_HEADER = b"\xfe\xfe\x00\x01"  # start word and version right; what follows makes the header


def reader(data: bytes, profile: Profile = P, *, extension: bool = True, cycle: Cycle = Cycle.UNKNOWN,
           eof: bool = False, probe_at: int | None = None) -> Reader:
    return Reader(data, profile, extension, cycle, eof, probe_at)


def resumes(r: Reader, p: int) -> set[int]:
    """Every offset a receiver may go on at after rejecting the bytes at ``p``, walking only bytes
    that are not a valid request (a valid frame is answered, never walked through)."""
    out: set[int] = set()
    todo = list(r.targets(p))
    while todo:
        q = todo.pop()
        if q in out:
            continue
        out.add(q)
        if q < r.n and r.spot(q).kind == BAD:
            todo.extend(r.targets(q))
    return out


# -- R6: every legal framing of bad bytes followed by a valid frame ---------------------------------


@pytest.mark.parametrize("k", range(1, 13))
def test_a_valid_frame_k_bytes_into_a_rejected_header_is_offered(k: int) -> None:
    """The first k bytes of a pose header, then a valid NONE: the header the receiver reads at 0
    is those k bytes plus the NONE's first 12-k, and no framing may hide the NONE from R6 (b)."""
    data = POSE_HEADER[:k] + NONE + POSE
    r = reader(data)
    first = r.spot(0)
    assert first.kind == BAD and first.exp is not None
    assert not first.exp.valid  # (c): a box may close after it (A5, R6)
    embedded = r.spot(k)
    assert embedded.kind == VALID and embedded.exp is not None and embedded.exp.action == Action.NONE
    assert embedded.end == k + len(NONE)
    # (b): the first FE FE searching from each offset 1..12 after the header's first byte
    assert {r.next_start(s) for s in range(1, 13)} <= resumes(r, 0)
    assert k in resumes(r, 0) and r.next_start(12) in resumes(r, 0)  # inside the header, and past all of it


def test_a_trusted_header_swallows_the_next_frame() -> None:
    """(a): a complete pose header announcing 25 block bytes takes the NONE behind it as its body."""
    r = reader(POSE_HEADER + NONE + POSE)
    spot = r.spot(0)
    assert spot.kind == BAD and spot.plausible and spot.end == len(POSE)
    assert spot.exp is not None and (spot.exp.rule, spot.exp.clause) == (Rule.REJECT, "B3")  # the NONE's FE index
    assert r.targets(0) == [len(POSE), 12]  # trust it, or resume where the NONE begins
    assert r.reference(0) == len(POSE)  # the codec's StreamDecoder trusts it


@pytest.mark.parametrize(("eof", "end", "waits", "targets"), [
    (False, -1, True, [4, 18]),  # trusting it means waiting for 256 block bytes: explain's terminal step
    (True, 4 + 14 + 39, False, [4 + 14 + 39, 4, 18]),  # the robot ended the stream: trusting it reaches the end
])
def test_a_plausible_header_announcing_more_than_was_sent(eof: bool, end: int, waits: bool, targets: list[int]) -> None:
    r = reader(HALF_HEADER + NONE + POSE, eof=eof)  # transfer type FE, and the NONE's bytes announce 1 x 256
    spot = r.spot(0)
    assert (spot.kind, spot.end, spot.plausible, spot.waits, spot.junk) == (BAD, end, True, waits, False)
    assert spot.exp is not None and (spot.exp.rule, spot.exp.clause) == (Rule.NOT_REQUEST, "F3")
    assert r.targets(0) == targets


def test_a_header_announcing_more_than_any_legal_frame_is_resynchronised_or_waited_on() -> None:
    """R5: 255 x 65535 block bytes is more than the largest legal frame: a receiver resynchronises, or trusts it
    only to skip what it announces and so waits (R6 a; explain.py), never answering 0000 (A5)."""
    huge = encode_raw(Header(action=Action.POSE, block_type=1, block_count=255, block_length=0xFFFF))
    r = reader(huge + NONE)
    spot = r.spot(0)
    assert (spot.kind, spot.end, spot.plausible, spot.junk, spot.waits) == (BAD, -1, False, True, True)
    assert spot.exp is not None and (spot.exp.rule, spot.exp.clause) == (Rule.NOT_REQUEST, "F5")
    assert r.targets(0) == [len(huge)] and r.reference(0) == len(huge)
    assert not reader(huge + NONE, eof=True).spot(0).waits  # the stream ended: nothing more to wait for


PIECES = [b"\xfe", b"\xfe\xfe", HALF_HEADER, b"\x00", b"\x01", b"\x23", b"\x19", b"\x10", b"\xff",
          NONE, POSE, POSE_HEADER, BAD_INDEX, encode(answer(Action.NONE))]


@given(st.lists(st.sampled_from(PIECES), min_size=1, max_size=10), st.booleans())
def test_the_ways_on_are_exactly_r6s(pieces: list[bytes], eof: bool) -> None:
    """At every rejected header: each resume offset 1..12 is reachable (a junk start word in
    between costs nothing and covers the later ones), and no target is something R6 does not allow."""
    r = reader(b"".join(pieces), eof=eof)
    for p in range(r.n):
        spot = r.spot(p)
        if spot.kind != BAD:
            continue
        if r.garbage(p):
            assert r.targets(p) == [r.next_start(p + 1)] == [spot.end]  # garbage ends at the next start word
            continue
        legal = {r.next_start(p + s) for s in range(1, 13)}
        assert set(r.targets(p)) <= legal | {spot.end}
        assert spot.end < 0 or spot.plausible or spot.end == r.n  # trusting needs a plausible header
        walked: set[int] = set()
        todo = list(r.targets(p))
        while todo:
            q = todo.pop()
            if q not in walked:
                walked.add(q)
                if q < r.n and r.spot(q).junk:
                    todo.extend(r.targets(q))
        assert legal <= walked


# -- what a receiver sees at one offset ----------------------------------------------------------------

SPOTS = [  # (id, data, Reader kwargs, kind, (rule, clause) or None, end, plausible, junk)
    ("garbage", b"hello" + NONE, {}, BAD, (Rule.NOT_REQUEST, "F1"), 5, False, True),
    ("lone-fe", b"\xfe", {}, PENDING, None, 0, False, False),  # may begin a start word
    ("lone-fe-eof", b"\xfe", {"eof": True}, BAD, (Rule.NOT_REQUEST, "F1"), 1, False, True),
    ("half-header", HALF_HEADER + b"\x01", {}, PENDING, None, 0, False, False),  # R3: the rest may come
    ("half-header-eof", HALF_HEADER + b"\x01", {"eof": True}, BAD, (Rule.NOT_REQUEST, "F5"), 5, False, True),
    ("short-bad-version", b"\xfe\xfe\x00\x02\x01", {}, BAD, (Rule.NOT_REQUEST, "F2"), -1, False, True),
    ("short-version-big", b"\xfe\xfe\x01", {}, BAD, (Rule.NOT_REQUEST, "F2"), -1, False, True),  # F4
    ("short-version-little", b"\xfe\xfe\x01", {"profile": Profile(byte_order="little")}, PENDING, None, 0, False,
     False),
    ("version", encode_raw(Header(version=2)) + NONE, {}, BAD, (Rule.NOT_REQUEST, "F2"), -1, False, True),
    ("cut-pose", POSE[:20], {}, PENDING, None, 0, False, False),
    ("cut-pose-eof", POSE[:20], {"eof": True}, BAD, (Rule.REJECT, "F5"), 20, True, False),
    ("b3", BAD_INDEX + NONE, {}, BAD, (Rule.REJECT, "B3"), 39, True, False),
    ("answer", encode(answer(Action.NONE)) + NONE, {}, BAD, (Rule.NOT_REQUEST, "F3"), 14, True, False),
    ("unknown-action", encode_raw(Header(action=0x99)) + NONE, {}, BAD, (Rule.NOT_REQUEST, "A5"), 14, True, False),
    ("27-without-e", encode(request(Action.VISION_RESULT)), {"extension": False}, BAD, (Rule.NOT_REQUEST, "A5"), 14,
     True, False),
    ("tcp-check", NONE[:-2] + b"\x12\x34", {}, BAD, (Rule.ANY, "F6"), 14, True, False),
    ("valid", NONE + POSE, {}, VALID, (Rule.ANSWER, ""), 14, False, False),
    ("crc", NONE[:-2] + P.check_bytes(NONE[:-2]), {}, VALID, (Rule.ANSWER_SHOULD, "F6"), 14, False, False),
]


@pytest.mark.parametrize(("data", "kw", "kind", "rule", "end", "plausible", "junk"), [s[1:] for s in SPOTS],
                         ids=[s[0] for s in SPOTS])
def test_what_a_receiver_sees_at_offset_0(data: bytes, kw: dict[str, Any], kind: str, rule: tuple[Rule, str] | None,
                                          end: int, plausible: bool, junk: bool) -> None:
    spot = reader(data, **kw).spot(0)
    assert spot.kind == kind
    assert (None if spot.exp is None else (spot.exp.rule, spot.exp.clause)) == rule
    assert (spot.end, spot.plausible, spot.junk) == (end, plausible, junk)


def test_the_cycle_state_and_the_probe_reach_the_expectations() -> None:
    off = encode(request(Action.CYCLE_OFF))
    assert reader(off, cycle=Cycle.ON).spot(0).exp == Expectation(
        Rule.ANSWER, "", Action.CYCLE_OFF, "robot→box CYCLE_OFF err=0x0000", ok_errors=frozenset({0, 2}))  # A3
    assert reader(off).spot(0).exp.ok_errors is None  # type: ignore[union-attr]  # S3: the state is unknown
    r = reader(b"hello" + NONE + NONE, probe_at=5)
    probe, after = r.spot(5).exp, r.spot(19).exp
    assert probe is not None and after is not None
    assert probe.probe and probe.message.startswith("the valid probe request behind the bytes")
    assert not after.probe and not r.spot(0).exp.probe  # type: ignore[union-attr]


@pytest.mark.parametrize(("data", "reference"), [
    (b"hello" + NONE, 5),  # past the garbage, to the next start word
    (BAD_INDEX + NONE, 39),  # the trusted frame's end
    (encode_raw(Header(version=2))[:12] + NONE, 12),  # untrusted: the next FE FE after its start word
    (b"\xfe\xfe\xfe" + NONE, 2),  # ... searching from its third byte: FE FE FE FE is one start word, then another
])
def test_the_reference_framing_is_the_stream_decoders(data: bytes, reference: int) -> None:
    assert reader(data).reference(0) == reference


# -- junk runs ---------------------------------------------------------------------------------------


def test_a_run_of_fe_ends_where_a_receiver_may_reach_the_valid_frame_behind_it() -> None:
    """64 KiB of FE: every offset is a start word with a wrong version (F2, not a request): one run,
    one junk event per offset (each may take one non-zero answer, A5). The last FE begins a header
    with two ways on (resume at the NONE one byte later, or past the whole header): the run stops there."""
    n = 65536
    r = reader(b"\xfe" * n + NONE)
    assert r.junk_run(0) == (n - 1, n - 1)
    assert r.junk_run(n - 1) is None and r.targets(n - 1) == [n, r.n]
    assert r.spot(n).kind == VALID and r.junk_run(n) is None


def test_a_run_entered_in_the_middle_agrees_with_one_walked_from_the_start() -> None:
    n = 4096
    r = reader(b"\xfe" * n + NONE)
    assert r.junk_run(n // 2) == (n - 1, n - 1 - n // 2)
    assert r.junk_run(0) == (n - 1, n - 1)  # reuses the cached tail
    assert r.junk_run(n - 2) == (n - 1, 1)


@pytest.mark.parametrize(("data", "run"), [
    (b"hello" + NONE, (5, 1)),  # garbage up to the start word
    (b"hello", (5, 1)),  # garbage to the end of the bytes
    (b"hello" + HALF_HEADER + NONE, (5, 1)),  # stops at a header a receiver may trust
    (b"hello" + BAD_INDEX, (5, 1)),  # ... or that has a request's action (A3, never junk)
    (b"hello\xfe\xfe\xfe" + NONE, (7, 3)),  # then F2 start words up to the last FE, which has two ways on
    (b"\xfe" + NONE, None),  # a junk header with two ways on (resume at 1, or past the header) is no run
    (NONE, None),
    (BAD_INDEX + NONE, None),
    (b"\xfe", None),  # pending, not junk
])
def test_a_junk_run_stops_where_a_receiver_has_a_choice(data: bytes, run: tuple[int, int] | None) -> None:
    assert reader(data).junk_run(0) == run


class _OneByOne(Reader):
    """The Reader without its FE shortcut: every offset classified, as before it."""

    def _fe_stretch(self, q: int) -> int:
        return q


_PIECES = st.sampled_from([b"\xfe" * 13, b"\xfe" * 40, b"\xfe", b"\xfe\xfe", NONE, POSE, POSE_HEADER, BAD_INDEX,
                           HALF_HEADER, b"hello", b"\x00"])


@given(st.lists(_PIECES, max_size=6), st.booleans())
def test_a_stretch_of_fe_walked_at_once_is_the_stretch_walked_offset_by_offset(pieces: list[bytes], eof: bool) -> None:
    """The shortcut over headers made of FE only (64 KiB of FE is 64k offsets) changes no run:
    every offset's run is the one the offset-by-offset walk finds."""
    data = b"".join(pieces)
    fast, slow = reader(data, eof=eof), _OneByOne(data, P, True, Cycle.UNKNOWN, eof)
    for p in range(len(data)):
        assert fast.junk_run(p) == slow.junk_run(p), p


# -- End and Explanation -----------------------------------------------------------------------------


def test_end_values() -> None:
    assert [e.value for e in End] == ["answered", "closed", "silent"]


def test_an_explanation_files_findings_by_level_and_answers_by_event() -> None:
    exp = Expectation(Rule.ANSWER, "", 0, "none")
    must = Finding(Level.MUST, "A1", "r", "o", "k1")
    should = Finding(Level.SHOULD, "R6", "r", "o", "k2")
    events = [Event(0, 5, exp, None), Event(5, 19, exp, 0), Event(19, 33, exp, 1), Event(33, 47, exp, 2)]
    ex = Explanation([should, must], events)
    assert ex.must == [must] and ex.should == [should] and ex.framing == "reference" and ex.unasked == []
    assert ex.answers_within(0, 19) == [0]  # the unanswered event at 0 contributes nothing
    assert ex.answers_within(5, 33) == [0, 1] and ex.answers_within(6, 19) == []  # by where events begin
    assert ex.event_at(19) is events[2] and ex.event_at(20) is None


def test_embedded_actions_are_the_action_bytes_at_every_start_word() -> None:
    none = encode(request(Action.NONE))
    assert embedded_actions(none) == {0x00}
    assert embedded_actions(b"\xfe" + none) == {0x00, 0x01}  # FE FE FE 00 01 01 00: at offset 0 the action byte is 01
    assert embedded_actions(b"garbage" + encode(request(Action.CYCLE_ON)) + b"\xfe\xfe\x00") == {0x01}  # cut header
    assert embedded_actions(b"no start word at all") == frozenset()

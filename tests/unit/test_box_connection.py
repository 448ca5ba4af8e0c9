"""One TCP connection of the reference box, sans-I/O: split and coalesced frames, the fast path
agreeing byte for byte with the decoder, the trace."""

import math
import struct

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from conformance.endpoints.behaviour import BoxBehaviour, BoxConfig, Reaction
from conformance.endpoints.box_connection import BoxConnection
from conformance.protocol import (
    DEFAULT_PROFILE,
    Action,
    Profile,
    Transport,
    encode_raw,
    tolerance_blocks,
    value_blocks,
)
from tests.unit.test_behaviour import POSE, _header, answers, box, pose_frame, req

pytestmark = pytest.mark.timeout(60)


# -- split, coalesced, and the fast path agreeing with the decoder ---------------------------------------------

SESSION = b"".join([
    req(Action.NONE), pose_frame(), req(Action.CYCLE_ON), pose_frame(), pose_frame((1, 2, 3, 4, 5, 6)),
    req(Action.TOLERANCE, tolerance_blocks([0.1])), req(Action.PROG_IDX, value_blocks([4])), pose_frame(),
    req(Action.CYCLE_OFF), req(Action.VISION_RESULT), pose_frame(),
])


def test_split_byte_by_byte_equals_whole():
    whole = BoxConnection(box()).receive_data(SESSION)
    conn = BoxConnection(box())
    pieces = b"".join(conn.receive_data(SESSION[i : i + 1]) for i in range(len(SESSION)))
    assert pieces == whole
    assert len(answers(whole)) == 11


def test_coalesced_poses_each_answered():
    b = box()
    out = BoxConnection(b).receive_data(pose_frame() * 100 + pose_frame()[:20])
    assert out == b.pose_ok * 100
    assert b.stats.requests == 100 and b.stats.answers == 100


def test_fast_path_checks_every_frame_of_a_chunk():
    bad = encode_raw(_header(0x23, 1, 1, 25), bytes([0]) + struct.pack(">6f", 0, 0, math.inf, 0, 0, 0))
    out = BoxConnection(box()).receive_data(pose_frame() * 5 + bad + pose_frame() * 5)
    assert [a.error_code for a in answers(out)] == [0] * 5 + [0x1001] + [0] * 5
    big = pose_frame((-3.0e38, 3.0e38, 0, 0, 0, 0))  # 0xff / 0x7f sign-exponent bytes, yet finite
    out = BoxConnection(box()).receive_data(big * 4)
    assert [a.error_code for a in answers(out)] == [0] * 4


def _reference(profile: Profile, chunks: list[bytes], config: BoxConfig) -> bytes:
    """The same bytes through the decoder and decide() only (a tracer disables the fast path)."""
    conn = BoxConnection(BoxBehaviour(config), trace=lambda *a: None)
    return b"".join(conn.receive_data(c) for c in chunks)


_PROFILES = [DEFAULT_PROFILE, Profile(float_byte_order="little"), Profile(byte_order="little"), Profile(first_index=1),
             Profile(strict=False)]


@st.composite
def _streams(draw):
    profile = draw(st.sampled_from(_PROFILES))
    floats = st.floats(width=32, allow_nan=True, allow_infinity=True)
    parts = []
    for _ in range(draw(st.integers(1, 25))):
        kind = draw(st.sampled_from(["pose", "pose", "pose", "poses", "other", "garbage", "bad-index", "cut"]))
        if kind == "pose":
            parts.append(pose_frame(tuple(draw(floats) for _ in range(6)), profile))
        elif kind == "poses":
            parts.append(pose_frame(POSE, profile) * draw(st.integers(2, 40)))
        elif kind == "other":
            action = draw(st.sampled_from([Action.NONE, Action.CYCLE_ON, Action.CYCLE_OFF, Action.VISION_RESULT]))
            parts.append(req(action, (), profile))
        elif kind == "bad-index":
            parts.append(pose_frame(POSE, profile, index=draw(st.integers(0, 255))))
        elif kind == "cut":
            parts.append(pose_frame(POSE, profile)[: draw(st.integers(1, 38))])
        else:
            parts.append(draw(st.binary(max_size=60)))
    data = b"".join(parts)
    cuts = sorted(draw(st.lists(st.integers(0, len(data)), max_size=12)))
    chunks = [data[a:b] for a, b in zip([0, *cuts], [*cuts, len(data)]) if b > a]
    return profile, chunks


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(_streams())
def test_fast_path_agrees_with_the_decoder(stream):
    profile, chunks = stream
    config = BoxConfig(profile=profile)
    conn = BoxConnection(BoxBehaviour(config))
    fast = b"".join(conn.receive_data(c) for c in chunks)
    assert fast == _reference(profile, chunks, config)


def test_a_wrapped_decide_sees_every_pose():
    b = box()
    original = b.decide
    seen = []

    def decide(event, transport=Transport.TCP):
        seen.append(event)
        return original(event, transport)

    b.decide = decide
    b.fast_path = False  # every frame through the patched decide()
    conn = BoxConnection(b)
    assert conn.receive_data(pose_frame() * 3) == b.pose_ok * 3
    assert len(seen) == 3
    b2 = box()
    b2.fast_path = False
    assert BoxConnection(b2).receive_data(pose_frame()) == b2.pose_ok


def test_trace_sees_every_event_with_its_bytes():
    seen = []
    conn = BoxConnection(box(), trace=lambda raw, event, decision: seen.append((raw, event, decision)))
    data = b"junk" + pose_frame() + req(Action.CYCLE_ON)
    for i in range(len(data)):
        conn.receive_data(data[i : i + 1])
    assert b"".join(raw for raw, _, _ in seen) == data
    # garbage fed a byte at a time is reported as it comes, each piece an F1 event
    assert [d.reaction for _, _, d in seen[-2:]] == [Reaction.OK, Reaction.OK]
    assert all(d.reaction is Reaction.SILENT and e.clause == "F1" for _, e, d in seen[:-2])

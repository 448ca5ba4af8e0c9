"""The robot's bytes decoded from transcripts, the F4 byte-order heuristic, and the wire logs."""

from __future__ import annotations

import struct

import pytest

from conformance.certify.wire_log import frame_wire, session_wire
from conformance.harness.transcript import Kind, Transcript, WireEvent
from conformance.observed.connections import BY_ROBOT
from conformance.observed.robot_frames import (
    FrameRecord,
    byte_order_evidence,
    compare_readings,
    decode_conn,
    decode_stream,
    judge_profile,
)
from conformance.protocol import (
    DEFAULT_PROFILE,
    Action,
    Frame,
    TcpCheckPolicy,
    encode,
    encode_udp,
    pose_blocks,
    request,
    value_blocks,
)
from tests.unit.test_observed_session import POSE, Fake, canonical, frame

HOME = (800.0, -100.0, 300.0, 180.0, 0.5, 0.0)


def transcript(*chunks: tuple[float, bytes], close: float | None = None) -> Transcript:
    tr = Transcript()
    tr.events += [WireEvent(t, 1, Kind.RECV, data) for t, data in chunks]
    if close is not None:
        tr.events.append(WireEvent(close, 1, Kind.PEER_CLOSE))
    return tr


def records(*chunks: tuple[float, bytes], close: float | None = None) -> list[FrameRecord]:
    return decode_stream(transcript(*chunks, close=close), judge_profile(DEFAULT_PROFILE))


def test_judging_profile_wants_zero_check():
    assert judge_profile(DEFAULT_PROFILE).tcp_check is TcpCheckPolicy.ZERO
    assert DEFAULT_PROFILE.tcp_check is TcpCheckPolicy.ZERO_OR_CRC


def test_frames_split_and_joined_get_the_time_of_their_last_byte():
    two = POSE + frame(Action.CYCLE_ON)
    out = records((1.0, two[:10]), (2.0, two[10:45]), (3.0, two[45:]))
    assert [r.t for r in out] == [2.0, 3.0]
    assert [r.offset for r in out] == [0, 39]
    assert [r.action for r in out] == [Action.POSE, Action.CYCLE_ON]
    assert out[0].raw == POSE and isinstance(out[0].event, Frame)


def test_garbage_and_errors_name_their_clause():
    out = records((1.0, b"hello" + POSE))
    assert out[0].error is not None and out[0].error.clause == "F1" and out[0].action is None
    assert out[1].action == Action.POSE and out[1].header_ok


def test_crc_in_the_tcp_check_is_f6_for_a_sender():
    body = POSE[:-2]
    with_crc = body + DEFAULT_PROFILE.check_bytes(body)
    (rec,) = records((1.0, with_crc))
    assert rec.error is not None and rec.error.clause == "F6"
    assert rec.action == Action.POSE  # still readable: the stream-level cases count it


def test_a_frame_cut_by_the_close_is_f5_at_the_time_of_its_bytes():
    out = records((1.0, POSE), (2.0, POSE[:20]), close=9.0)
    assert out[-1].error is not None and out[-1].error.clause == "F5"
    assert out[-1].t == 2.0


def test_a_direction_error():
    reply = bytearray(POSE)
    reply[4] = 0x10
    (rec,) = records((1.0, bytes(reply)))
    assert rec.error is not None and rec.error.clause == "F3"


def test_udp_datagrams():
    fake = Fake()
    conn = fake.conn(0.0, "udp")
    good = encode_udp(request(Action.NONE))
    fake.send(conn, 0.1, good)
    fake.send(conn, 0.2, good[:-1] + bytes([good[-1] ^ 1]))
    out = decode_conn(conn, DEFAULT_PROFILE)
    assert isinstance(out[0].event, Frame) and out[0].transport == "udp"
    assert out[1].error is not None and out[1].error.clause == "F7" and out[1].offset == 1


# -- F4 ------------------------------------------------------------------------------------------------
def _pose(order: str, values=HOME, first: int = 0) -> FrameRecord:
    profile = DEFAULT_PROFILE.replace(float_byte_order=order)
    data = encode(request(Action.POSE, pose_blocks([values], first)), profile)
    return FrameRecord(1, "tcp", 0.0, 0, data, Frame.__new__(Frame))  # the event is not looked at


def test_byte_order_evidence():
    assert byte_order_evidence(_pose("big"), DEFAULT_PROFILE) == "straight"
    assert byte_order_evidence(_pose("little"), DEFAULT_PROFILE) == "swapped"
    assert byte_order_evidence(_pose("big", (0.0,) * 6), DEFAULT_PROFILE) is None
    little = DEFAULT_PROFILE.replace(float_byte_order="little")
    assert byte_order_evidence(_pose("little"), little) == "straight"
    assert byte_order_evidence(_pose("big"), little) == "swapped"


def test_tiny_residues_do_not_hide_the_evidence():
    values = (812.345, -97.5, 251.0, 179.99, 1e-17, 0.0)
    assert byte_order_evidence(_pose("little", values), DEFAULT_PROFILE) == "swapped"
    assert byte_order_evidence(_pose("big", values), DEFAULT_PROFILE) == "straight"


def test_little_endian_header_and_program_index():
    header = bytearray(POSE)
    header[2:4] = b"\x01\x00"
    rec = FrameRecord(1, "tcp", 0.0, 0, bytes(header), Frame.__new__(Frame))
    assert byte_order_evidence(rec, DEFAULT_PROFILE) == "swapped"
    little = DEFAULT_PROFILE.replace(float_byte_order="little")
    prog = encode(request(Action.PROG_IDX, value_blocks([7])), little)
    assert byte_order_evidence(FrameRecord(1, "tcp", 0, 0, prog, Frame.__new__(Frame)), DEFAULT_PROFILE) == "swapped"
    prog = encode(request(Action.PROG_IDX, value_blocks([7])))
    assert byte_order_evidence(FrameRecord(1, "tcp", 0, 0, prog, Frame.__new__(Frame)), DEFAULT_PROFILE) == "straight"


@pytest.mark.parametrize("straight, swapped, expected", [
    ((800.0, 1.0), (2e-41, 4e-41), "straight"),
    ((2e-41, 4e-41), (800.0, 1.0), "swapped"),
    ((float("nan"), 3e38 * 10), (800.0, 1.0), "swapped"),
    ((0.0, 0.0), (0.0, 0.0), None),
    ((800.0, float("nan")), (1e-40, 7.0), None),
])
def test_compare_readings(straight, swapped, expected):
    assert compare_readings(straight, swapped) == expected


def test_struct_reading_matches_the_codec():
    data = _pose("little").raw
    assert struct.unpack_from("<6f", data, 13) == pytest.approx(HOME)


# -- wire logs -------------------------------------------------------------------------------------------------
def test_session_wire_keeps_the_ends_of_the_pose_traffic():
    fake, cmd, stream = canonical()
    lines = session_wire(fake.session.conns, DEFAULT_PROFILE, 0.0, keep_poses=2)
    omitted = [w for w in lines if "pose traffic omitted" in w.summary]
    assert len(omitted) == 1 and omitted[0].conn == stream.number
    assert sum(1 for w in lines if w.conn == stream.number and w.kind == Kind.RECV) == 4  # 2 first, 2 last
    assert any(w.direction == "←" and "CYCLE_ON" in w.summary for w in lines)
    assert any(w.direction == "→" and "box→robot CYCLE_ON" in w.summary for w in lines)
    connects = [w for w in lines if w.kind == Kind.CONNECT]
    assert connects[0].summary.startswith("accepted from robot") and "(command, tcp" in connects[0].summary
    assert [w.t_ms for w in lines] == sorted(w.t_ms for w in lines)
    assert cmd.closed_by == BY_ROBOT


def test_session_wire_is_bounded():
    fake = Fake()
    conn = fake.conn(0.0)
    for i in range(50):
        fake.send(conn, 0.01 * i, frame(Action.NONE))
    lines = session_wire(fake.session.conns, DEFAULT_PROFILE, 0.0, limit=20)
    assert len(lines) == 20 and "more lines in the pcap" in lines[-1].summary


def test_frame_wire_quotes_the_frame_and_the_answer():
    out = records((1.5, b"xx" + POSE))
    lines = frame_wire(out, 1.0, {(1, 0): "nothing", (1, 2): "box→robot POSE err=0x0000"})
    assert lines[0].t_ms == 500.0 and lines[0].hex == "78 78" and "[F1]" in lines[0].summary
    assert lines[-1].direction == "→" and "POSE err=0x0000" in lines[-1].summary

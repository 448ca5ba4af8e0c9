"""The reference box's behaviour, sans-I/O: no sockets, no clocks."""

import json
import math
import struct
from pathlib import Path

import pytest

from conformance.endpoints.behaviour import (
    BOX_STATES,
    CONDITIONS,
    MALFORMED,
    REACTION_ANSWER,
    SENDABLE_RESULTS,
    TRANSITIONS,
    BoxBehaviour,
    BoxConfig,
    Cycle,
    Reaction,
)
from conformance.endpoints.box_connection import BoxConnection
from conformance.protocol import (
    DEFAULT_PROFILE,
    REQUEST_SHAPE,
    Action,
    ErrorCode,
    Frame,
    Header,
    Profile,
    StreamDecoder,
    TransferType,
    Transport,
    codec_for,
    encode,
    encode_raw,
    pose_blocks,
    request,
    tolerance_blocks,
    value_blocks,
)

pytestmark = pytest.mark.timeout(60)

ROOT = Path(__file__).resolve().parents[2]
POSE = (812.5, -100.25, 250.0, 180.0, 4.5, -0.5)


def req(action, blocks=(), profile=DEFAULT_PROFILE):
    return encode(request(action, blocks), profile)


def pose_frame(pose=POSE, profile=DEFAULT_PROFILE, index=None):
    first = profile.first_index if index is None else index
    return req(Action.POSE, pose_blocks([pose], first), profile)


def answers(data: bytes, profile=DEFAULT_PROFILE):
    """Every answer frame in ``data`` (a box's output), parsed."""
    events = StreamDecoder(profile, TransferType.BOX_TO_ROBOT).feed(data)
    for event in events:
        assert isinstance(event, Frame), f"the box sent a malformed answer: {event}"
    return events


def one_answer(data: bytes, profile=DEFAULT_PROFILE) -> Frame:
    got = answers(data, profile)
    assert len(got) == 1, got
    return got[0]


def box(**knobs):
    return BoxBehaviour(BoxConfig(**knobs))


# -- the tables ---------------------------------------------------------------------------------------


def test_transition_table_is_complete():
    for action in REQUEST_SHAPE:
        for state in BOX_STATES:
            for cond in (True, False):
                assert (state, action, cond) in TRANSITIONS, (state, action, cond)
        assert action in MALFORMED
    assert set(CONDITIONS) <= set(REQUEST_SHAPE)
    assert set(BoxConfig().conditions) == set(CONDITIONS.values())


def test_tables_never_answer_a_malformed_request_0000():
    for action, reaction in MALFORMED.items():
        if reaction in (Reaction.SILENT, Reaction.CLOSE):
            continue
        code, _ = REACTION_ANSWER[reaction]
        assert code != ErrorCode.OK, action
    assert REACTION_ANSWER[MALFORMED[Action.POSE]][0] == ErrorCode.POSE_ERROR
    assert REACTION_ANSWER[MALFORMED[Action.REGISTER_POSE]][0] == ErrorCode.POSE_ERROR
    assert REACTION_ANSWER[MALFORMED[Action.TOLERANCE]][0] == ErrorCode.TOLERANCE_ERROR


def test_config_validation():
    for code in SENDABLE_RESULTS:
        BoxConfig(vision_result=code)
    for bad in (0, 3, 404, -1):
        with pytest.raises(ValueError, match="vision result"):
            BoxConfig(vision_result=bad)
    with pytest.raises(ValueError):
        BoxConfig(latency_ms=-1)
    with pytest.raises(ValueError):
        BoxConfig(on_garbage="explode")


# -- well-formed requests -------------------------------------------------------------------------------


def test_canonical_cycle():
    b = box()
    conn = BoxConnection(b)
    assert one_answer(conn.receive_data(req(Action.NONE))) == Frame(TransferType.BOX_TO_ROBOT, Action.NONE)
    assert one_answer(conn.receive_data(pose_frame())).error_code == 0  # S3: before CycleOn
    on = one_answer(conn.receive_data(req(Action.CYCLE_ON)))
    assert (on.action, on.error_code, on.blocks) == (Action.CYCLE_ON, 0, ())
    assert b.state is Cycle.ON
    assert one_answer(conn.receive_data(pose_frame())).error_code == 0
    assert one_answer(conn.receive_data(req(Action.REGISTER_POSE, pose_blocks([POSE])))).error_code == 0
    assert one_answer(conn.receive_data(req(Action.TOLERANCE, tolerance_blocks([0.5, 1.5])))).error_code == 0
    off = one_answer(conn.receive_data(req(Action.CYCLE_OFF)))
    assert (off.action, off.error_code) == (Action.CYCLE_OFF, 0)
    assert b.state is Cycle.IDLE


def test_s3_informational_cases_answer_0000_with_a_note():
    b = box()
    d = b.decide(request(Action.CYCLE_OFF))
    assert d.frame.error_code == 0 and "S3" in d.note and b.state is Cycle.IDLE
    b.decide(request(Action.CYCLE_ON))
    d = b.decide(request(Action.CYCLE_ON))
    assert d.frame.error_code == 0 and "S3" in d.note and b.state is Cycle.ON


def test_not_ready_answers_0001_and_keeps_the_cycle_off():
    b = box(not_ready=True)
    d = b.decide(request(Action.CYCLE_ON))
    assert d.frame.error_code == ErrorCode.NOT_READY and b.state is Cycle.IDLE
    assert b.decide(request(Action.POSE, pose_blocks([POSE]))).frame.error_code == 0


def test_cycle_off_failure_answers_0002_and_keeps_the_cycle_on():
    b = box(cycle_off_fails=True)
    b.decide(request(Action.CYCLE_ON))
    d = b.decide(request(Action.CYCLE_OFF))
    assert d.frame.error_code == ErrorCode.CYCLE_OFF_FAILED and b.state is Cycle.ON


def test_reconfigure_keeps_state():
    b = box()
    b.decide(request(Action.CYCLE_ON))
    b.configure(BoxConfig(cycle_off_fails=True))
    assert b.state is Cycle.ON
    assert b.decide(request(Action.CYCLE_OFF)).frame.error_code == ErrorCode.CYCLE_OFF_FAILED


def test_request_error_field_is_ignored():
    b = box()
    d = b.decide(request(Action.CYCLE_ON, error_code=1))
    assert d.frame.error_code == 0


@pytest.mark.parametrize("index", [7, 0, -1, 2**31 - 1, -(2**31)])
def test_prog_idx_echoes_the_index(index):
    b = box()
    a = one_answer(BoxConnection(b).receive_data(req(Action.PROG_IDX, value_blocks([index]))))
    assert (a.action, a.error_code, [blk.value for blk in a.blocks]) == (Action.PROG_IDX, 0, [index])
    assert a.blocks[0].index == 0
    assert b.prog_idx == index


def test_prog_idx_conflict_409_in_the_block():
    a = box(progidx_conflict=True).decide(request(Action.PROG_IDX, value_blocks([3]))).frame
    assert (a.error_code, a.blocks[0].value) == (0, 409)


def test_prog_idx_conflict_409_in_the_error_field_too():
    profile = Profile(progidx_conflict="error-code")
    a = box(progidx_conflict=True, profile=profile).decide(request(Action.PROG_IDX, value_blocks([3]))).frame
    assert (a.error_code, a.blocks[0].value) == (409, 409)


@pytest.mark.parametrize("code", SENDABLE_RESULTS)
def test_vision_result_codes(code):
    a = one_answer(BoxConnection(box(vision_result=code)).receive_data(req(Action.VISION_RESULT)))
    assert (a.action, a.error_code, a.blocks[0].value, a.blocks[0].index) == (Action.VISION_RESULT, 0, code, 0)


def test_first_index_1_profile_answers_blocks_from_1():
    profile = Profile(first_index=1)
    b = box(profile=profile)
    a = one_answer(BoxConnection(b).receive_data(req(Action.PROG_IDX, value_blocks([5], 1), profile)), profile)
    assert a.blocks[0].index == 1 and a.blocks[0].value == 5
    assert one_answer(BoxConnection(b).receive_data(pose_frame(profile=profile)), profile).error_code == 0
    bad = pose_frame(profile=profile, index=0)
    assert one_answer(BoxConnection(b).receive_data(bad), profile).error_code == ErrorCode.POSE_ERROR


@pytest.mark.parametrize("action", [Action.PROG_IDX, Action.VISION_RESULT])
def test_extension_off_makes_26_27_unknown(action):
    blocks = value_blocks([1]) if action is Action.PROG_IDX else ()
    b = box(extension=False)
    conn = BoxConnection(b)
    assert conn.receive_data(req(action, blocks)) == b""
    assert b.stats.not_requests == 1
    # and the connection is still in step
    assert one_answer(conn.receive_data(pose_frame())).error_code == 0
    # a malformed 26/27 is silent too
    bad = encode_raw(Header(action=action, block_type=3, block_count=2, block_length=5), bytes(10))
    assert conn.receive_data(bad) == b""


# -- malformed requests (A3) and bytes that are not requests (A5) ------------------------------------------


def _header(action, bt, n, length, **kw):
    return Header(action=action, block_type=bt, block_count=n, block_length=length, **kw)


MALFORMED_CASES = [
    # (name, bytes, expected error code or None for silence)
    ("pose index gap", encode_raw(_header(0x23, 1, 2, 25), bytes([0]) + bytes(24) + bytes([2]) + bytes(24)), 0x1001),
    ("pose index from 1", encode_raw(_header(0x23, 1, 1, 25), bytes([1]) + bytes(24)), 0x1001),
    ("pose without blocks", encode_raw(_header(0x23, 0, 0, 0)), 0x1001),
    ("pose with a tolerance block", encode_raw(_header(0x23, 2, 1, 5), bytes(5)), 0x1001),
    ("pose with L=24", encode_raw(_header(0x23, 1, 1, 24), bytes(24)), 0x1001),
    ("pose NaN", encode_raw(_header(0x23, 1, 1, 25), bytes([0]) + struct.pack(">6f", math.nan, 0, 0, 0, 0, 0)), 0x1001),
    ("pose inf", encode_raw(_header(0x23, 1, 1, 25), bytes([0]) + struct.pack(">6f", 0, 0, 0, 0, 0, -math.inf)), 0x1001),
    ("pose TCP check BEEF", encode_raw(_header(0x23, 1, 1, 25), bytes(25), b"\xbe\xef"), 0x1001),
    ("register pose index gap", encode_raw(_header(0x24, 1, 1, 25), bytes([3]) + bytes(24)), 0x1001),
    ("tolerance without blocks", encode_raw(_header(0x25, 0, 0, 0)), 0x1002),
    ("tolerance with a pose block", encode_raw(_header(0x25, 1, 1, 25), bytes(25)), 0x1002),
    ("tolerance NaN", encode_raw(_header(0x25, 2, 1, 5), bytes([0]) + struct.pack(">f", math.nan)), 0x1002),
    ("CycleOn with a block", encode_raw(_header(0x01, 2, 1, 5), bytes(5)), 0x0001),
    ("CycleOff with L=5", encode_raw(_header(0x02, 0, 0, 5)), 0x0002),
    ("ProgIdx without a block", encode_raw(_header(0x26, 0, 0, 0)), 400),
    ("result request with a block", encode_raw(_header(0x27, 3, 1, 5), bytes(5)), 400),
    ("action 00 with a block", encode_raw(_header(0x00, 2, 1, 5), bytes(5)), None),
    ("version 2", encode_raw(Header(version=2)), None),
    ("transfer type 10", encode_raw(Header(transfer_type=0x10)), None),
    ("transfer type 02", encode_raw(Header(transfer_type=0x02, action=0x23, block_type=1, block_count=1,
                                           block_length=25), bytes(25)), None),
    ("unknown action 30", encode_raw(Header(action=0x30)), None),
    ("garbage", b"hello, box! this is not a frame", None),
]


@pytest.mark.parametrize("name,data,code", MALFORMED_CASES, ids=[c[0] for c in MALFORMED_CASES])
def test_malformed_and_not_requests(name, data, code):
    b = box()
    conn = BoxConnection(b)
    out = conn.receive_data(data)
    if code is None:
        assert out == b"", "A5: silence"
    else:
        got = one_answer(out)
        assert got.error_code == code
        assert got.action == data[5]
        if code == 400:  # 26/27: ResultCode 400 in the block as well
            assert got.blocks[0].value == 400
    assert not conn.should_close
    # R6: in step again for the next frame
    assert one_answer(conn.receive_data(pose_frame())).error_code == 0


def test_lenient_profile_accepts_non_finite_and_either_first_index():
    profile = Profile(strict=False)
    conn = BoxConnection(box(profile=profile))
    nan_pose = encode_raw(_header(0x23, 1, 1, 25), bytes([0]) + struct.pack(">6f", math.nan, 0, 0, 0, 0, 0))
    assert [a.error_code for a in answers(conn.receive_data(nan_pose * 3))] == [0, 0, 0]
    assert len(answers(conn.receive_data(pose_frame(index=1) * 2))) == 2


def test_oversize_announcement_is_answered_1001_and_skipped():
    conn = BoxConnection(box())
    header = encode_raw(_header(0x23, 1, 255, 0xFFFF))[:12]
    out = conn.receive_data(header + bytes(1000) + pose_frame())
    got = answers(out)
    assert [a.error_code for a in got] == [0x1001, 0]
    assert conn.buffered < 39


def test_close_on_garbage_knob():
    conn = BoxConnection(box(on_garbage="close"))
    assert conn.receive_data(pose_frame()) == box().pose_ok
    assert conn.receive_data(b"\x00\x01garbage") == b""
    assert conn.should_close


def test_never_0000_to_any_invalid_vector():
    """Every robot→box golden vector: invalid → never 0000; valid/acceptable → one echoing answer."""
    checked = 0
    for path in sorted((ROOT / "vectors" / "frames").glob("*.json")):
        for group in json.loads(path.read_text())["testGroups"]:
            if group["direction"] != "robot-to-box":
                continue
            prof = group.get("profile", {})
            profile = Profile(crc=group.get("crc", "modbus"), first_index=prof.get("firstIndex", 0),
                              crc_byte_order=prof.get("crcByteOrder", "big"))
            for test in group["tests"]:
                data = bytes.fromhex(test["hex"])
                b = box(profile=profile)
                if group["transport"] == "tcp":
                    out = BoxConnection(b).receive_data(data) if data else b""
                else:
                    out = b.receive_datagram(data) or b""
                    if out:
                        codec_for(profile).parse(out, Transport.UDP, TransferType.BOX_TO_ROBOT)  # a correct CRC
                        out = out[:-2] + b"\x00\x00"
                got = answers(out, profile)
                label = f"{path.name} #{test['tcId']} {test['comment'][:60]}"
                if test["result"] == "invalid":
                    assert all(a.error_code != 0 for a in got), label
                    if "F7" in test["clauses"][:1] or (group["transport"] == "udp" and "F5" in test["clauses"][:1]):
                        assert got == [], f"R7: dropped silently: {label}"
                else:
                    assert len(got) == 1, label
                    assert got[0].action == data[5], label
                    if test["result"] == "valid":
                        assert got[0].error_code == 0, label
                checked += 1
    assert checked > 100


# -- UDP (F7, R7) --------------------------------------------------------------------------------------------------


@pytest.mark.parametrize("profile", [Profile(), Profile(crc="xmodem"), Profile(crc="kermit", crc_byte_order="little")],
                         ids=["modbus", "xmodem", "kermit-little"])
def test_datagrams(profile):
    b = box(profile=profile)
    codec = codec_for(profile)
    good = codec.encode(request(Action.POSE, pose_blocks([POSE])), Transport.UDP)
    out = b.receive_datagram(good)
    a = codec.parse(out, Transport.UDP, TransferType.BOX_TO_ROBOT)
    assert (a.action, a.error_code) == (Action.POSE, 0)
    # wrong CRC, two frames in one datagram, a cut datagram: dropped silently (R7)
    wrong = good[:-2] + bytes([good[-2] ^ 0xFF, good[-1]])
    assert b.receive_datagram(wrong) is None
    assert b.receive_datagram(good + good) is None
    assert b.receive_datagram(good[:20]) is None
    assert b.receive_datagram(b"") is None
    assert b.stats.dropped_datagrams == 4
    # malformed but CRC-correct: A3's answer, with a correct CRC
    bad = codec.encode_raw(_header(0x23, 1, 1, 25), bytes([9]) + bytes(24), transport=Transport.UDP)
    a = codec.parse(b.receive_datagram(bad), Transport.UDP, TransferType.BOX_TO_ROBOT)
    assert a.error_code == 0x1001
    # a TCP-style 00 00 check is a wrong CRC over UDP
    assert b.receive_datagram(codec.encode(request(Action.CYCLE_ON))) is None


def test_the_box_picks_its_answers_from_the_protocol_table():
    """Every well-formed request's answer is one the protocol's table allows (protocol/answers.py): the
    box picks from the table the oracle, the cases and certify read; a knob cannot make it drift."""
    from conformance.protocol.answers import allowed_codes

    for config in (BoxConfig(), BoxConfig(not_ready=True), BoxConfig(cycle_off_fails=True),
                   BoxConfig(progidx_conflict=True)):
        b = BoxBehaviour(config)
        for (state, action), (decision, _) in b._table.items():
            allowed = allowed_codes(action, state)
            assert decision.frame is not None
            assert allowed is None or decision.frame.error_code in allowed, (config, state, action)

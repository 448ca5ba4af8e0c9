"""The scapy layer (conformance/evidence/scapy_layer.py) against the golden vectors
in vectors/frames/*.json, plus hand-built frames and a never-raises property."""

from __future__ import annotations

import json
import math
import struct
from pathlib import Path
from typing import Any

import pytest
from hypothesis import given
from hypothesis import strategies as st
from scapy.layers.inet import IP, TCP, UDP
from scapy.packet import Raw

from conformance.evidence.scapy_layer import (
    MAX_CHAIN,
    ISight,
    ISightPose,
    ISightRawBlock,
    ISightTolerance,
    ISightValue,
    bind_port,
    crc16,
    crc_ok,
    frames,
    from_dict,
    to_dict,
    unbind_port,
    with_udp_crc,
)
from conformance.protocol import DEFAULT_PROFILE

ROOT = Path(__file__).resolve().parents[2]
VECTOR_DIR = ROOT / "vectors" / "frames"
_SPECIAL_FLOATS = {"NaN": math.nan, "Infinity": math.inf, "-Infinity": -math.inf}


# -- golden vectors ------------------------------------------------------------------


def _load_vectors() -> list[Any]:
    cases: list[tuple[str, dict[str, Any], dict[str, Any]]] = []
    for path in sorted(VECTOR_DIR.glob("*.json")):
        doc = json.loads(path.read_text(encoding="utf-8"))
        for group in doc["testGroups"]:
            for tc in group["tests"]:
                cases.append((path.stem, group, tc))
    params = []
    for stem, group, tc in cases:
        name = f"{group['transport']}-{group['direction']}-tc{tc['tcId']}"
        if not name.startswith(stem):  # tcIds repeat across files: name the file too
            name = f"{stem}-{name}"
        params.append(pytest.param(group, tc, id=name))
    return params


VECTORS = _load_vectors()


def _cases(keep: Any) -> Any:
    """Parametrise over the vectors ``keep`` selects; with none, one failing case."""
    chosen = [p for p in VECTORS if keep(*p.values)]
    return pytest.mark.parametrize("group, tc", chosen or [pytest.param(None, None, id="no-vectors")])


def _need(group: Any) -> None:
    if group is None:
        pytest.fail(f"no golden vectors found in {VECTOR_DIR}/*.json")


def _crc_order(group: dict[str, Any]) -> str:
    return str(group.get("profile", {}).get("crcByteOrder", "big"))


def _quiet_nans(raw: bytes, frame: dict[str, Any]) -> bytes:
    """``raw`` with every float the vector gives as "NaN" set to 7FC00000: the
    vector format keeps a NaN's sign and payload only in the hex."""
    out = bytearray(raw)
    for k, block in enumerate(frame["blocks"]):
        floats = block.get("pose", [block.get("tolerance")])
        for j, value in enumerate(floats):
            if value == "NaN":
                at = 12 + k * frame["blockLength"] + 1 + 4 * j
                assert math.isnan(struct.unpack(">f", raw[at : at + 4])[0])
                out[at : at + 4] = bytes.fromhex("7fc00000")
    return bytes(out)


def _expected(value: Any) -> Any:
    """The vector's frame with "NaN"/"Infinity"/"-Infinity" turned into floats."""
    if isinstance(value, str) and value in _SPECIAL_FLOATS:
        return _SPECIAL_FLOATS[value]
    if isinstance(value, list):
        return [_expected(v) for v in value]
    if isinstance(value, dict):
        return {k: _expected(v) for k, v in value.items()}
    return value


def _mismatch(actual: Any, expected: Any, where: str = "frame") -> str | None:
    """None when equal (NaN equals NaN, ints must be ints); else where they differ."""
    if isinstance(expected, dict):
        if not isinstance(actual, dict) or actual.keys() != expected.keys():
            return f"{where}: keys {sorted(actual) if isinstance(actual, dict) else actual!r}"
        for k in expected:
            found = _mismatch(actual[k], expected[k], f"{where}.{k}")
            if found:
                return found
        return None
    if isinstance(expected, list):
        if not isinstance(actual, list) or len(actual) != len(expected):
            return f"{where}: {actual!r} != {expected!r}"
        for i, (a, e) in enumerate(zip(actual, expected, strict=True)):
            found = _mismatch(a, e, f"{where}[{i}]")
            if found:
                return found
        return None
    if isinstance(expected, float):
        same = isinstance(actual, float) and (actual == expected or (math.isnan(actual) and math.isnan(expected)))
    elif isinstance(expected, int) and not isinstance(expected, bool):
        same = type(actual) is int and actual == expected
    else:
        same = actual == expected
    return None if same else f"{where}: {actual!r} != {expected!r}"


@_cases(lambda group, tc: True)
def test_vector_dissects_without_error(group: Any, tc: Any) -> None:
    """Every vector, valid or not: dissection never raises and keeps the bytes."""
    _need(group)
    raw = bytes.fromhex(tc["hex"])
    if not raw:
        return  # scapy reads no bytes as "all defaults": nothing to dissect
    pkt = ISight(raw)
    assert bytes(pkt) == raw
    for frame in frames(pkt):
        to_dict(frame)


_accepted = _cases(lambda group, tc: tc["result"] in ("valid", "acceptable"))


@_accepted
def test_vector_to_dict(group: Any, tc: Any) -> None:
    _need(group)
    got = to_dict(ISight(bytes.fromhex(tc["hex"])))
    problem = _mismatch(got, _expected(tc["frame"]))
    assert problem is None, f"tc{tc['tcId']} ({tc['comment']}): {problem}"


@_accepted
def test_vector_rebuild(group: Any, tc: Any) -> None:
    _need(group)
    want = _quiet_nans(bytes.fromhex(tc["hex"]), tc["frame"])
    frame = _expected(tc["frame"])
    assert bytes(from_dict(frame)).hex() == want.hex()
    # ... and by hand, field by field.
    blocks = [
        ISightPose(index=b["index"], **dict(zip("xyzwpr", b["pose"], strict=True)))
        if "pose" in b
        else ISightTolerance(index=b["index"], tolerance=b["tolerance"])
        if "tolerance" in b
        else ISightValue(index=b["index"], value=b["value"])
        for b in frame["blocks"]
    ]
    pkt = ISight(
        start_word=frame["startWord"],
        version=frame["version"],
        transfer_type=frame["transferType"],
        action=frame["action"],
        block_type=frame["blockType"],
        block_count=frame["blockCount"],
        block_length=frame["blockLength"],
        error_code=frame["errorCode"],
        check=frame["check"],
        blocks=blocks,
    )
    assert bytes(pkt).hex() == want.hex()


@_cases(lambda group, tc: group["transport"] == "udp" and tc["result"] == "valid")
def test_vector_udp_crc(group: Any, tc: Any) -> None:
    _need(group)
    order = _crc_order(group)
    raw = bytes.fromhex(tc["hex"])
    profile = DEFAULT_PROFILE.replace(crc=group["crc"], crc_byte_order=order)
    assert crc_ok(raw, profile)
    if _quiet_nans(raw, tc["frame"]) == raw:  # else the dict cannot give these bytes
        unchecked = dict(_expected(tc["frame"]), check=0)
        assert with_udp_crc(from_dict(unchecked), profile) == raw


def test_vector_files_exist() -> None:
    assert VECTORS, f"no golden vectors found in {VECTOR_DIR}/*.json"


# -- hand-built frames ---------------------------------------------------------------


def _pose_request(n: int = 1, first: int = 0) -> ISight:
    return ISight(
        action="pose",
        blocks=[ISightPose(index=first + i, x=1.5 * i, y=-2.25, z=3, w=180, p=-0.5, r=90) for i in range(n)],
    )


def test_build_computes_header() -> None:
    pkt = _pose_request(2)
    raw = bytes(pkt)
    assert raw[:12] == bytes.fromhex("fefe 0001 01 23 01 02 0019 0000")
    assert len(raw) == 12 + 2 * 25 + 2 and raw[-2:] == b"\0\0"
    assert raw[12] == 0 and raw[12 + 25] == 1
    assert struct.unpack(">f", raw[13:17]) == (0.0,)
    assert struct.unpack(">f", raw[38:42]) == (1.5,)
    d = to_dict(pkt)
    assert (d["blockType"], d["blockCount"], d["blockLength"]) == (1, 2, 25)
    assert d["blocks"][1] == {"index": 1, "pose": [1.5, -2.25, 3.0, 180.0, -0.5, 90.0]}
    value = bytes(ISight(transfer_type="box_to_robot", action="prog_idx", blocks=[ISightValue(value=-409)]))
    assert value == bytes.fromhex("fefe 0001 10 26 03 01 0005 0000 00 fffffe67 0000")
    assert bytes(ISight(transfer_type=0x10, action=0x23)) == bytes.fromhex("fefe000110230000000000000000")


def test_explicit_header_fields_override() -> None:
    raw = bytes(ISight(action=0x23, block_type=2, block_count=3, block_length=25, blocks=[ISightPose()]))
    assert raw[6:10] == bytes.fromhex("02 03 0019")
    assert len(raw) == 12 + 25 + 2


def test_several_frames_in_one_tcp_payload() -> None:
    one, two = _pose_request(1), _pose_request(3)
    tol = ISight(action="tolerance", blocks=[ISightTolerance(index=0, tolerance=0.5)])
    payload = bytes(one) + bytes(two) + bytes(tol)
    pkt = IP(bytes(IP() / TCP(sport=40000, dport=9004) / Raw(payload)))
    layers = list(frames(pkt))
    assert [to_dict(f)["blockCount"] for f in layers] == [1, 3, 1]
    assert isinstance(pkt[TCP].payload, ISight)
    assert isinstance(pkt[TCP].payload.payload, ISight)
    assert isinstance(pkt[TCP].payload.payload.payload, ISight)
    assert layers[2].blocks[0].tolerance == 0.5
    assert bytes(pkt[TCP].payload) == payload


def test_answers_on_source_port_9004() -> None:
    answer = ISight(transfer_type="box_to_robot", action="cycle_on")
    pkt = IP(bytes(IP() / TCP(sport=9004, dport=40000) / answer))
    assert to_dict(pkt)["transferType"] == 0x10
    built = IP() / TCP() / ISight()
    assert built[TCP].dport == 9004  # bind_layers fills it in


def test_udp_frame_on_9004_with_crc() -> None:
    datagram = with_udp_crc(_pose_request(2))
    pkt = IP(bytes(IP() / UDP(sport=40000, dport=9004) / Raw(datagram)))
    assert pkt.haslayer(ISight)
    assert to_dict(pkt)["check"] == crc16(datagram[:-2])
    assert crc_ok(bytes(pkt[ISight]))
    assert crc_ok(pkt)
    assert not crc_ok(datagram[:-1] + bytes([datagram[-1] ^ 1]))
    xmodem = DEFAULT_PROFILE.replace(crc="xmodem", crc_byte_order="little")
    little = with_udp_crc(_pose_request(1), xmodem)
    assert crc_ok(little, xmodem) and not crc_ok(little, xmodem.replace(crc_byte_order="big"))
    assert int.from_bytes(little[-2:], "little") == crc16(little[:-2], "xmodem")


@pytest.fixture
def port_5000():
    bind_port(5000)
    yield 5000
    unbind_port(5000)


def test_bind_port(port_5000: int) -> None:
    raw = bytes(IP() / TCP(sport=40000, dport=port_5000) / Raw(bytes(_pose_request(1))))
    assert IP(raw).haslayer(ISight)
    raw_udp = bytes(IP() / UDP(sport=port_5000, dport=40000) / Raw(bytes(ISight())))
    assert IP(raw_udp).haslayer(ISight)
    unbind_port(port_5000)
    assert not IP(raw).haslayer(ISight)
    assert IP(bytes(IP() / TCP(dport=9004) / Raw(bytes(ISight())))).haslayer(ISight)


def test_port_5000_not_bound_by_default() -> None:
    raw = bytes(IP() / TCP(sport=40000, dport=5000) / Raw(bytes(ISight())))
    assert not IP(raw).haslayer(ISight)


def test_malformed_block_length_gives_raw_blocks() -> None:
    # pose type but L = 5: two raw blocks of 5 bytes, then the check field.
    body = bytes(range(10))
    raw = bytes.fromhex("fefe 0001 01 23 01 02 0005 0000") + body + b"\x12\x34"
    pkt = ISight(raw)
    assert [type(b) for b in pkt.blocks] == [ISightRawBlock, ISightRawBlock]
    assert [b.data for b in pkt.blocks] == [body[:5], body[5:]]
    assert pkt.check == 0x1234 and bytes(pkt) == raw
    assert to_dict(pkt)["blocks"] == [{"raw": body[:5].hex()}, {"raw": body[5:].hex()}]
    assert bytes(from_dict(to_dict(pkt))) == raw
    # unknown block type 7 with a pose-sized L: raw too.
    odd = bytes.fromhex("fefe 0001 01 23 07 01 0019 0000") + bytes(25) + b"\0\0"
    assert isinstance(ISight(odd).blocks[0], ISightRawBlock) and bytes(ISight(odd)) == odd
    # tolerance type with L = 0 and N = 3: no block bytes at all.
    empty = bytes.fromhex("fefe 0001 01 25 02 03 0000 0000 0000")
    assert ISight(empty).blocks == [] and to_dict(ISight(empty))["check"] == 0


def test_truncated_frames() -> None:
    full = bytes(_pose_request(2))
    for cut in range(1, len(full)):
        pkt = ISight(full[:cut])
        assert bytes(pkt) == full[:cut]
        assert to_dict(pkt)["check"] is None
    short = to_dict(ISight(full[:5]))
    assert short["startWord"] == 0xFEFE and short["transferType"] == 1 and short["action"] is None
    last_cut = ISight(full[:30])  # 12 header + 18 bytes of the first pose block
    assert [type(b) for b in last_cut.blocks] == [ISightRawBlock]
    assert "truncated" in last_cut.summary()


def test_many_frames_in_one_segment() -> None:
    one = bytes(ISight(transfer_type=0x10, action=0x23))
    n = 3 * MAX_CHAIN + 7  # e.g. a loopback capture: segments up to 64 KiB
    pkt = IP(bytes(IP() / TCP(sport=9004) / Raw(one * n)))
    got = list(frames(pkt))
    assert len(got) == n and all(bytes(f)[:14] == one for f in got)
    assert bytes(pkt[TCP].payload) == one * n
    assert len(list(frames(one * n + b"\xfe"))) == n


@pytest.mark.parametrize(
    "algorithm, check",
    [("modbus", 0x4B37), ("xmodem", 0x31C3), ("kermit", 0x2189), ("crc-16", 0xBB3D), ("x-25", 0x906E)],
)
def test_crc16_check_values(algorithm: str, check: int) -> None:
    assert crc16(b"123456789", algorithm) == check


def test_crc16_rejects_other_widths() -> None:
    with pytest.raises(ValueError):
        crc16(b"123456789", "crc-32")
    with pytest.raises(ValueError):
        crc16(b"123456789", "no-such-crc")


# -- properties ----------------------------------------------------------------------


def _dissects_cleanly(data: bytes) -> None:
    if not data:
        return  # ISight(b"") is a default-built frame, not a dissection
    pkt = ISight(data)
    assert bytes(pkt) == data
    for frame in frames(pkt):
        to_dict(frame)
        frame.summary()


@given(st.binary(max_size=400))
def test_any_bytes_never_raise(data: bytes) -> None:
    _dissects_cleanly(data)


_header_ish = st.builds(
    lambda t, a, bt, n, length, rest: (
        bytes.fromhex("fefe0001") + bytes([t, a, bt, n]) + length.to_bytes(2, "big") + rest
    ),
    st.sampled_from([0x01, 0x10, 0x00, 0xFF]),
    st.sampled_from([0x00, 0x01, 0x02, 0x23, 0x24, 0x25, 0x26, 0x27, 0x99]),
    st.integers(0, 4),
    st.integers(0, 255),
    st.sampled_from([0, 1, 4, 5, 6, 24, 25, 26, 0xFFFF]),
    st.binary(max_size=80),
)


@given(st.lists(_header_ish, max_size=6))
def test_header_like_bytes_never_raise(parts: list[bytes]) -> None:
    _dissects_cleanly(b"".join(parts))


_f32 = st.floats(width=32, allow_nan=False)
_index = st.integers(0, 255)
_one_kind: list[st.SearchStrategy[Any]] = [
    st.builds(
        lambda i, v: ISightPose(index=i, **dict(zip("xyzwpr", v, strict=True))),
        _index,
        st.lists(_f32, min_size=6, max_size=6),
    ),
    st.builds(lambda i, t: ISightTolerance(index=i, tolerance=t), _index, _f32),
    st.builds(lambda i, v: ISightValue(index=i, value=v), _index, st.integers(-(2**31), 2**31 - 1)),
]
# The blocks of one frame are all of one kind.
_block_lists = st.sampled_from(_one_kind).flatmap(lambda kind: st.lists(kind, max_size=5))


@given(
    st.sampled_from([0x01, 0x10]),
    st.sampled_from([0x00, 0x01, 0x02, 0x23, 0x24, 0x25, 0x26, 0x27]),
    st.sampled_from([0x0000, 0x0001, 0x0002, 0x1001, 0x1002]),
    _block_lists,
)
def test_build_dissect_round_trip(transfer: int, action: int, error: int, blocks: list[Any]) -> None:
    raw = bytes(ISight(transfer_type=transfer, action=action, error_code=error, blocks=blocks))
    d = to_dict(ISight(raw))
    assert d["blockCount"] == len(blocks) and len(raw) == 14 + d["blockCount"] * d["blockLength"]
    assert bytes(from_dict(d)) == raw
    assert bytes(from_dict({k: v for k, v in d.items() if k not in ("blockType", "blockCount", "blockLength")})) == raw

"""The golden vectors through the codec: conformance.evidence.vectors_file and conformance.protocol agree
with bytes derived by hand (vectors/frames/*.json)."""

from __future__ import annotations

import math

import pytest

from conformance.evidence.vectors_file import Vector, frame_from_dict, frame_to_dict, load, load_dir, write
from conformance.protocol import (
    CLOSED,
    Frame,
    ProtocolError,
    StreamDecoder,
    TcpCheckPolicy,
    Transport,
    encode,
    parse_frame,
)

VECTORS = load_dir()


def _same(a: object, b: object) -> bool:
    """Equality where NaN equals NaN (vector floats may be "NaN")."""
    if isinstance(a, float) and isinstance(b, float):
        return (math.isnan(a) and math.isnan(b)) or (a == b and math.copysign(1, a) == math.copysign(1, b))
    if isinstance(a, (list, tuple)) and isinstance(b, (list, tuple)):
        return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b))
    if isinstance(a, dict) and isinstance(b, dict):
        return a.keys() == b.keys() and all(_same(a[k], b[k]) for k in a)
    return a == b


def _expected(vector: Vector) -> dict:
    assert vector.frame is not None
    return _normalise(dict(vector.frame))


def _normalise(d: dict) -> dict:
    def fl(v):  # type: ignore[no-untyped-def]
        return float({"NaN": "nan", "Infinity": "inf", "-Infinity": "-inf"}.get(v, v)) if isinstance(v, (str, float)) else v

    out = dict(d)
    out["blocks"] = [
        {k: ([fl(x) for x in v] if k == "pose" else fl(v) if k == "tolerance" else v) for k, v in b.items()}
        for b in d["blocks"]
    ]
    return out


def test_there_are_enough_vectors() -> None:
    assert len(VECTORS) >= 80
    assert {v.result for v in VECTORS} == {"valid", "invalid", "acceptable"}


@pytest.mark.parametrize("vector", [v for v in VECTORS if v.result == "valid"], ids=lambda v: v.name)
def test_valid_vectors_decode_to_their_frame(vector: Vector) -> None:
    frame = parse_frame(vector.data, vector.profile, vector.transport, vector.direction)
    assert _same(_normalise(frame_to_dict(frame)), _expected(vector))
    # and the frame encodes back to the same bytes
    assert encode(frame, vector.profile, vector.transport) == vector.data


@pytest.mark.parametrize("vector", [v for v in VECTORS if v.result == "invalid"], ids=lambda v: v.name)
def test_invalid_vectors_are_rejected_naming_their_clause(vector: Vector) -> None:
    with pytest.raises(ProtocolError) as info:
        parse_frame(vector.data, vector.profile, vector.transport, vector.direction)
    assert info.value.clause == vector.clauses[0], f"{info.value} for: {vector.comment}"


@pytest.mark.parametrize("vector", [v for v in VECTORS if v.result == "acceptable"], ids=lambda v: v.name)
def test_acceptable_vectors_decode_or_are_rejected_for_their_reason(vector: Vector) -> None:
    try:
        frame = parse_frame(vector.data, vector.profile, vector.transport, vector.direction)
    except ProtocolError as exc:
        assert exc.clause in vector.clauses, f"{exc} for: {vector.comment}"
    else:
        assert _same(_normalise(frame_to_dict(frame)), _expected(vector))
    # the most lenient reading accepts every acceptable vector
    lenient = vector.profile.replace(strict=False, tcp_check=TcpCheckPolicy.IGNORE)
    frame = parse_frame(vector.data, lenient, vector.transport, vector.direction)
    assert _same(_normalise(frame_to_dict(frame)), _expected(vector))


@pytest.mark.parametrize("vector", [v for v in VECTORS if v.transport is Transport.TCP], ids=lambda v: v.name)
def test_stream_decoder_agrees_with_the_frame_parser(vector: Vector) -> None:
    dec = StreamDecoder(vector.profile, vector.direction)
    events = dec.feed(vector.data)
    events += dec.feed(b"")
    assert dec.next_event() is CLOSED
    assert events, "the stream decoder reported nothing"
    if vector.result == "valid":
        assert len(events) == 1 and isinstance(events[0], Frame)
        assert _same(_normalise(frame_to_dict(events[0])), _expected(vector))
    elif vector.result == "invalid":
        assert isinstance(events[0], ProtocolError), events
        assert events[0].clause in vector.clauses, f"{events[0]} for: {vector.comment}"


@pytest.mark.parametrize("vector", [v for v in VECTORS if v.frame is not None][:40], ids=lambda v: v.name)
def test_frame_from_dict_round_trips(vector: Vector) -> None:
    frame = frame_from_dict(vector.frame)  # type: ignore[arg-type]
    assert _same(_normalise(frame_to_dict(frame)), _normalise({**_expected(vector), "check": frame.check}))


def test_write_then_load_round_trips(tmp_path) -> None:  # type: ignore[no-untyped-def]
    groups = [{"transport": "tcp", "crc": "modbus", "direction": "robot-to-box", "tests": [
        {"tcId": 1, "comment": "c", "clauses": ["B3"], "flags": [], "result": "invalid", "hex": "fefe"},
    ]}]
    path = tmp_path / "v.json"
    write(path, groups, description="found by the fuzzer")
    (loaded,) = list(load(path))
    assert loaded.data == b"\xfe\xfe" and loaded.clauses == ("B3",) and loaded.result == "invalid"
    assert not list(tmp_path.glob("*.tmp"))

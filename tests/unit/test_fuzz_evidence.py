"""Fuzz evidence (conformance/fuzz/failure_files.py): vector files that validate and load, pcaps, summaries."""

from __future__ import annotations

import json
from pathlib import Path

import jsonschema

from conformance.evidence.vectors_file import REPO_VECTORS, frame_from_dict, load
from conformance.fuzz.failure_files import Failure, clauses_of, write_pcap, write_summary, write_vectors
from conformance.fuzz.strategies import Strategies
from conformance.harness.transcript import Endpoint, Kind, Transcript
from conformance.protocol import Action, Profile, Transport, encode, encode_udp, pose_blocks, request

SCHEMA = json.loads((REPO_VECTORS / "isight-vectors-1.schema.json").read_text(encoding="utf-8"))
S = Strategies(Profile(), udp=True)
VALID = S.case("valid", "", encode(request(Action.POSE, pose_blocks([(1.5, -2.0, 0.0, -0.0, 1e-45, 3.0)]))), "pose")
BAD = S.case("B3-index", "B3", encode(request(Action.POSE, pose_blocks([(0.0,) * 6], 1))), "bad index")
UDP = S.case("F7-crc", "F7", encode_udp(request(Action.NONE))[:-1] + b"\x00", "bad crc", Transport.UDP)
CUT = S.case("F5-truncated", "F5", BAD.data[:20], "cut", eof=True)


def test_a_failure_becomes_a_schema_valid_vector_file_that_loads(tmp_path: Path) -> None:
    failure = Failure(1, "context", ["A1"], "the box did something", [VALID, BAD, UDP, CUT])
    path = write_vectors(tmp_path / "f.json", failure, Profile(), "test")
    doc = json.loads(path.read_text())
    jsonschema.validate(doc, SCHEMA)
    assert doc["numberOfTests"] == 4 and [g["transport"] for g in doc["testGroups"]] == ["tcp", "udp"]
    vectors = list(load(path))
    by_hex = {v.data: v for v in vectors}
    valid = by_hex[VALID.wire]
    assert valid.result == "valid" and frame_from_dict(valid.frame).blocks[0].pose[4] == VALID_POSE_5
    assert by_hex[BAD.wire].result == "invalid" and by_hex[BAD.wire].clauses[0] == "B3"
    assert by_hex[UDP.wire].result == "invalid" and by_hex[UDP.wire].clauses[0] == "F7"
    assert by_hex[CUT.data].result == "invalid" and "in this order on one connection" in by_hex[CUT.data].comment


VALID_POSE_5 = 1.401298464324817e-45  # float32(1e-45): the smallest subnormal


def test_clauses_put_the_decoder_s_first_and_only_known_ids() -> None:
    assert clauses_of(BAD, ["R2", "nonsense", "A3/R1"]) == ["B3", "R2", "A3", "R1"]
    assert clauses_of(VALID) == ["A1"]


def test_the_pcap_is_the_transcript_and_the_summary_is_json(tmp_path: Path) -> None:
    tr = Transcript("FUZZ-001")
    c = tr.open("tcp", Endpoint("127.0.0.1", 40000), Endpoint("127.0.0.1", 9004), "fuzz")
    tr.add(c.conn, Kind.CONNECT)
    tr.add(c.conn, Kind.SEND, BAD.wire, "the case")
    tr.add(c.conn, Kind.CLOSE)
    pcap = write_pcap(tr, tmp_path / "pcaps" / "f.pcapng")
    data = pcap.read_bytes()
    assert data[:4] == b"\x0a\x0d\x0d\x0a" and BAD.wire in data and b"FUZZ-001: the case" in data
    out = write_summary(tmp_path / "s" / "fuzz-summary.json", {"seed": 1, "path": tmp_path})
    assert json.loads(out.read_text())["seed"] == 1

"""Checks the golden frame vectors in vectors/frames/ as data.

Deliberately independent of the codec in conformance/: frames are taken apart here
with struct and bytes.fromhex only (plus crcmod for the UDP check field), following
PROTOCOL.md, so a slip in the vectors and a slip in the codec cannot hide each other.
"""
import json
import math
import struct
from pathlib import Path

import crcmod.predefined
import jsonschema
import pytest

ROOT = Path(__file__).resolve().parents[2]
SCHEMA_PATH = ROOT / "vectors" / "isight-vectors-1.schema.json"
FRAME_FILES = sorted((ROOT / "vectors" / "frames").glob("*.json"))

REQUIRED_CLAUSES = {f"F{i}" for i in range(1, 8)} | {f"B{i}" for i in range(1, 6)} \
    | {f"A{i}" for i in range(2, 6)} | {f"E{i}" for i in range(1, 4)}
REQ, ANS = 0x01, 0x10
KNOWN_ACTIONS = {0x00, 0x01, 0x02, 0x23, 0x24, 0x25, 0x26, 0x27}
LISTED_ERRORS = {0x0000, 0x0001, 0x0002, 0x1001, 0x1002}
LISTED_RESULTS = {1, 2, 10, 20, 202, 400, 409}
# A3 pairs each non-zero error code with the action(s) it belongs to.
ERROR_ACTIONS = {0x0001: {0x01}, 0x0002: {0x02}, 0x1001: {0x23, 0x24}, 0x1002: {0x25}}


def load(path):
    with open(path, encoding="utf-8") as fh:
        return json.load(fh)


def all_tests():
    for path in FRAME_FILES:
        for group in load(path)["testGroups"]:
            for test in group["tests"]:
                yield path.name, group, test


def test_there_are_vector_files():
    assert FRAME_FILES, "no vector files in vectors/frames/"


# ---------------------------------------------------------------------------------
# per-file checks


@pytest.fixture(scope="module")
def validator():
    schema = load(SCHEMA_PATH)
    jsonschema.Draft202012Validator.check_schema(schema)
    return jsonschema.Draft202012Validator(schema)


@pytest.mark.parametrize("path", FRAME_FILES, ids=lambda p: p.name)
def test_file_matches_schema(path, validator):
    errors = sorted(validator.iter_errors(load(path)), key=lambda e: list(e.path))
    assert not errors, "\n".join(f"{list(e.path)}: {e.message}" for e in errors[:10])


@pytest.mark.parametrize("path", FRAME_FILES, ids=lambda p: p.name)
def test_counts_ids_and_flags(path):
    doc = load(path)
    tests = [t for g in doc["testGroups"] for t in g["tests"]]
    assert doc["numberOfTests"] == len(tests)
    ids = [t["tcId"] for t in tests]
    assert len(ids) == len(set(ids)), "duplicate tcId"
    used = {f for t in tests for f in t["flags"]}
    assert used <= set(doc["notes"]), f"flags without a note: {used - set(doc['notes'])}"
    assert set(doc["notes"]) <= used, f"notes for unused flags: {set(doc['notes']) - used}"


@pytest.mark.parametrize("path", FRAME_FILES, ids=lambda p: p.name)
def test_no_hex_twice_in_a_group(path):
    for group in load(path)["testGroups"]:
        seen = [t["hex"] for t in group["tests"]]
        assert len(seen) == len(set(seen)), "the same bytes appear twice in one group"


# ---------------------------------------------------------------------------------
# an independent reading of a frame, straight from PROTOCOL.md


def crc_fun(name):
    return crcmod.predefined.mkPredefinedCrcFun(name)


def profile(group):
    p = group.get("profile", {})
    return p.get("firstIndex", 0), p.get("crcByteOrder", "big")


def check_field(raw):
    """frame.check: the check field read big-endian like every field (F4), whatever the profile."""
    return int.from_bytes(raw[-2:], "big")


def crc_on_wire(group, body):
    """The two check bytes a UDP sender in this group writes after ``body`` (F7)."""
    return crc_fun(group["crc"])(body).to_bytes(2, profile(group)[1])


def float_json(b):
    x = struct.unpack(">f", b)[0]
    if math.isnan(x):
        return "NaN"
    if math.isinf(x):
        return "Infinity" if x > 0 else "-Infinity"
    return x


def frame_violation(raw, group):
    """First clause the bytes break as a frame, checking in the order README.md documents;
    None if they break no MUST (SHOULD-level matters such as NaN are not reported)."""
    if len(raw) < 12:
        return "F5"
    sw, ver, tt, act, bt, n, blen, err = struct.unpack(">HHBBBBHH", raw[:12])
    if sw != 0xFEFE:
        return "F1"
    if ver != 0x0001:
        return "F2"
    request = group["direction"] == "robot-to-box"
    if tt != (REQ if request else ANS):
        return "F3"
    if act not in KNOWN_ACTIONS:
        return "A5"
    # header shape for the action (B5 / A2 / E1-E3)
    if act == 0x26 or (act == 0x27 and not request):
        owner = "E2" if act == 0x26 else "E3"
        if bt != 0x03:
            return owner
        if blen != 5:
            return "E1"
        if n != 1:
            return owner
    elif act in (0x23, 0x24, 0x25) and request:
        want_type, want_len, len_clause = (0x01, 25, "B1") if act != 0x25 else (0x02, 5, "B2")
        if bt != want_type:
            return "B5"
        if blen != want_len:
            return len_clause
        if n < 1:
            return "B5"
    elif (bt, n, blen) != (0, 0, 0):
        if not request:
            return "A2"
        return "E3" if act == 0x27 else "B5"
    if len(raw) != 12 + n * blen + 2:
        return "F5"
    if group["transport"] == "udp" and raw[-2:] != crc_on_wire(group, raw[:-2]):
        return "F7"
    first = profile(group)[0]
    indexes = [raw[12 + i * blen] for i in range(n)]
    if indexes != list(range(first, first + n)):
        return "B3"
    return None


def content_violation(raw, group):
    """MUST rules on a well-formed answer's content (README order, step 8)."""
    if group["direction"] == "robot-to-box":
        return None
    act, err = raw[5], struct.unpack(">H", raw[10:12])[0]
    if act == 0x00 and err != 0:
        return "A4"
    if act == 0x27 and struct.unpack(">i", raw[13:17])[0] in (0, 404):
        return "E3"
    return None


def first_violation(raw, group):
    return frame_violation(raw, group) or content_violation(raw, group)


def decode(raw, group):
    sw, ver, tt, act, bt, n, blen, err = struct.unpack(">HHBBBBHH", raw[:12])
    blocks = []
    for i in range(n):
        blk = raw[12 + i * blen: 12 + (i + 1) * blen]
        if bt == 0x01:
            blocks.append({"index": blk[0], "pose": [float_json(blk[k:k + 4]) for k in range(1, 25, 4)]})
        elif bt == 0x02:
            blocks.append({"index": blk[0], "tolerance": float_json(blk[1:5])})
        elif bt == 0x03:
            blocks.append({"index": blk[0], "value": struct.unpack(">i", blk[1:5])[0]})
        else:
            raise AssertionError(f"block type {bt:#04x} in a valid/acceptable vector")
    return {"startWord": sw, "version": ver, "transferType": tt, "action": act, "blockType": bt,
            "blockCount": n, "blockLength": blen, "errorCode": err,
            "check": check_field(raw), "blocks": blocks}


def assert_same_float(expected, wire_bytes):
    """expected is the JSON value; it must be the exact float32 on the wire, sign of zero included."""
    if isinstance(expected, str):
        assert float_json(wire_bytes) == expected
        return
    assert isinstance(expected, (int, float)) and not isinstance(expected, bool)
    packed = struct.pack(">f", expected)
    assert struct.unpack(">f", packed)[0] == expected, f"{expected!r} is not exactly a float32"
    assert packed == wire_bytes, f"{expected!r} packs to {packed.hex()}, wire has {wire_bytes.hex()}"


def nonfinite(frame):
    for blk in frame["blocks"]:
        values = blk.get("pose", []) + ([blk["tolerance"]] if "tolerance" in blk else [])
        if any(isinstance(v, str) for v in values):
            return True
    return False


def flag_holds(flag, frame, group, raw):
    request = group["direction"] == "robot-to-box"
    err, act = frame["errorCode"], frame["action"]
    body_crc = crc_fun(group["crc"])(raw[:-2])
    return {
        "NonFinite": lambda: nonfinite(frame),
        "TcpCrcCheck": lambda: group["transport"] == "tcp" and frame["check"] == body_crc != 0,
        "TcpNonZeroCheck": lambda: group["transport"] == "tcp" and frame["check"] not in (0, body_crc),
        "RequestErrorCode": lambda: request and err != 0,
        "UnlistedErrorCode": lambda: not request and err not in LISTED_ERRORS,
        "ErrorCodeActionMismatch": lambda: not request and err in ERROR_ACTIONS
        and act not in ERROR_ACTIONS[err],
        "UnlistedResultCode": lambda: not request and act == 0x27
        and frame["blocks"][0]["value"] not in LISTED_RESULTS | {0, 404},
        "ExtAnswerErrorCode": lambda: not request and act in (0x26, 0x27) and err != 0,
        "Extension": lambda: act in (0x26, 0x27),
    }[flag]()


def vector_id(item):
    name, group, test = item
    return f"{name}#{test['tcId']}"


ALL = list(all_tests())


@pytest.mark.parametrize("item", [i for i in ALL if i[2]["result"] != "invalid"], ids=vector_id)
def test_valid_and_acceptable_hex_matches_frame(item):
    _, group, test = item
    raw, frame = bytes.fromhex(test["hex"]), test["frame"]
    assert len(raw) == 12 + frame["blockCount"] * frame["blockLength"] + 2
    assert raw[0:2] == struct.pack(">H", frame["startWord"]) == b"\xfe\xfe"
    assert raw[2:4] == struct.pack(">H", frame["version"]) == b"\x00\x01"
    for key in ("startWord", "version", "transferType", "action", "blockType", "blockCount",
                "blockLength", "errorCode", "check"):
        assert type(frame[key]) is int, f"{key} is not a JSON integer"
    assert len(frame["blocks"]) == frame["blockCount"]
    decoded = decode(raw, group)
    header = {k: v for k, v in decoded.items() if k != "blocks"}
    assert header == {k: v for k, v in frame.items() if k != "blocks"}
    for got, want, i in zip(decoded["blocks"], frame["blocks"], range(frame["blockCount"])):
        assert got.keys() == want.keys() and got["index"] == want["index"]
        blk = raw[12 + i * frame["blockLength"]: 12 + (i + 1) * frame["blockLength"]]
        if "pose" in want:
            for k, v in enumerate(want["pose"]):
                assert_same_float(v, blk[1 + 4 * k: 5 + 4 * k])
        elif "tolerance" in want:
            assert_same_float(want["tolerance"], blk[1:5])
        else:
            assert type(want["value"]) is int and want["value"] == got["value"]


@pytest.mark.parametrize("item", ALL, ids=vector_id)
def test_result_agrees_with_an_independent_reading(item):
    """valid/acceptable break no MUST; an invalid vector's first clause is the first it breaks."""
    _, group, test = item
    found = first_violation(bytes.fromhex(test["hex"]), group)
    if test["result"] == "invalid":
        assert found == test["clauses"][0], f"first violation {found}, vector says {test['clauses']}"
    else:
        assert found is None, f"{test['result']} vector breaks {found}"


@pytest.mark.parametrize("item", [i for i in ALL if i[2]["result"] != "invalid"], ids=vector_id)
def test_flags_describe_the_frame(item):
    _, group, test = item
    raw = bytes.fromhex(test["hex"])
    for flag in test["flags"]:
        assert flag_holds(flag, test["frame"], group, raw), f"flag {flag} does not hold"
    if test["result"] == "valid":
        # a valid vector may only be marked as using the extension; anything else is a
        # reason to accept-or-reject and belongs to an acceptable vector.
        assert set(test["flags"]) <= {"Extension"}
        assert not nonfinite(test["frame"])
        if group["transport"] == "tcp":
            assert test["frame"]["check"] == 0


@pytest.mark.parametrize("item", [i for i in ALL if i[2]["result"] == "invalid"], ids=vector_id)
def test_flags_on_invalid_vectors(item):
    _, group, test = item
    raw = bytes.fromhex(test["hex"])
    uses_ext = len(raw) > 5 and raw[5] in (0x26, 0x27)
    assert ("Extension" in test["flags"]) == uses_ext
    # AnswerContent marks exactly the invalid vectors that are well-formed frames
    assert ("AnswerContent" in test["flags"]) == (frame_violation(raw, group) is None)
    assert set(test["flags"]) <= {"Extension", "AnswerContent"}


# ---------------------------------------------------------------------------------
# totals over all files


def test_totals_and_coverage():
    tests = [t for _, _, t in ALL]
    assert len(tests) >= 90
    clauses = {c for t in tests for c in t["clauses"]}
    assert REQUIRED_CLAUSES <= clauses, f"clauses never used: {sorted(REQUIRED_CLAUSES - clauses)}"
    for result in ("valid", "invalid", "acceptable"):
        assert any(t["result"] == result for t in tests), result
    groups = [g for _, g, _ in ALL]
    assert {g["transport"] for g in groups} == {"tcp", "udp"}
    assert {g["direction"] for g in groups} == {"robot-to-box", "box-to-robot"}
    assert len({g["crc"] for g in groups if g["transport"] == "udp"}) >= 3
    assert any(g.get("profile", {}).get("crcByteOrder") == "little" for g in groups)
    assert any(g.get("profile", {}).get("firstIndex") == 1 for g in groups)
    for transport in ("tcp", "udp"):
        for direction in ("robot-to-box", "box-to-robot"):
            assert any(g["transport"] == transport and g["direction"] == direction for g in groups)


@pytest.mark.parametrize("name", ["modbus", "xmodem", "kermit", "crc-16", "x-25"])
def test_crc_functions_match_published_check_values(name):
    published = {"modbus": 0x4B37, "xmodem": 0x31C3, "kermit": 0x2189, "crc-16": 0xBB3D, "x-25": 0x906E}
    assert crc_fun(name)(b"123456789") == published[name]

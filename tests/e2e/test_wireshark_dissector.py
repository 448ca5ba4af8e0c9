"""The Wireshark Lua dissector (conformance/wireshark/isight.lua) against tshark.

For every test group of the golden vectors (vectors/frames/*.json) one pcap is written
(every vector in its own TCP connection with a 3-way handshake, or its own UDP
datagram) and tshark runs once over it with the group's preferences. Valid and
acceptable vectors must decode to exactly their `frame`; invalid vectors that the
dissector sees as a frame must carry expert info naming one of the vector's clauses.
Further tests: loading, TCP reassembly (one frame in 3 segments, 3 frames in one
segment), the heuristic dissectors on other ports, every crcmod CRC-16, oversize
headers (R5) and garbage before a frame (R6).

Skipped only when tshark is not installed.
"""

from __future__ import annotations

import json
import math
import os
import shutil
import struct
import subprocess
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import crcmod.predefined
import pytest

from conformance.protocol.profile import crc16_names
from tests.pcaputil import TcpConnection, udp_datagram, write_pcap

ROOT = Path(__file__).resolve().parents[2]
# ISIGHT_DISSECTOR: test another copy of the script (e.g. a deliberately broken one)
LUA = Path(os.environ.get("ISIGHT_DISSECTOR", ROOT / "conformance" / "wireshark" / "isight.lua"))
VECTOR_DIR = ROOT / "vectors" / "frames"
TSHARK = shutil.which("tshark")
SERVER_PORT = 9004
HEUR_TCP_PORT = 47700  # nothing registered there: only the heuristic can claim it
HEUR_UDP_PORT = 47701

pytestmark = [
    pytest.mark.tshark,
    pytest.mark.skipif(TSHARK is None, reason="tshark is not installed (apt-get install tshark)"),
]

# Clauses whose invalid vectors the dissector must see and flag whenever it sees a frame.
MUST_FLAG = {"F1", "F2", "F3", "A5", "B3", "B5", "F6", "F7"}
# SHOULD-level deviations the dissector warns about on "acceptable" vectors.
WARN_ON_ACCEPTABLE = {"F6", "B4"}
ISIGHT_EXPERTS = ("isight.malformed", "isight.protocol", "isight.warning", "isight.bad_crc")
ERROR_EXPERTS = ("isight.malformed", "isight.protocol", "isight.bad_crc")

HEADER_FIELDS = {
    "startWord": "isight.start_word",
    "version": "isight.version",
    "transferType": "isight.transfer_type",
    "action": "isight.action",
    "blockType": "isight.block_type",
    "blockCount": "isight.block_count",
    "blockLength": "isight.block_length",
    "errorCode": "isight.error_code",
    "check": "isight.check",
}
POSE_FIELDS = [f"isight.pose.{c}" for c in "xyzwpr"]


# ------------------------------------------------------------------------------------
# vectors
# ------------------------------------------------------------------------------------
def _load_groups() -> list[tuple[str, dict]]:
    groups = []
    for path in sorted(VECTOR_DIR.glob("*.json")):
        doc = json.loads(path.read_text())
        assert doc.get("schema") == "isight-vectors-1", f"{path.name}: unknown schema {doc.get('schema')!r}"
        for gi, group in enumerate(doc["testGroups"]):
            profile = group.get("profile") or {}
            gid = f"{path.stem}#{gi}-{group['transport']}-{group['crc']}-{group['direction']}"
            if profile:
                gid += "-" + "-".join(f"{k}={v}" for k, v in sorted(profile.items()))
            groups.append((gid, group))
    return groups


GROUPS = _load_groups()


def _valid_hex(transport: str, direction: str | None = None) -> list[str]:
    """Hex of the valid vectors of default-profile groups (for the transport tests)."""
    out = []
    for _, g in GROUPS:
        if g["transport"] != transport or g.get("profile") or g["crc"] != "modbus":
            continue
        if direction and g["direction"] != direction:
            continue
        out += [t["hex"] for t in g["tests"] if t["result"] == "valid"]
    return out


# ------------------------------------------------------------------------------------
# tshark
# ------------------------------------------------------------------------------------
def _prefs(crc: str = "modbus", byte_order: str = "big", first_index: int = 0, extra: dict | None = None) -> list[str]:
    prefs = {"isight.crc_algorithm": crc, "isight.crc_byte_order": byte_order, "isight.first_index": str(first_index)}
    prefs.update(extra or {})
    args = []
    for k, v in prefs.items():
        args += ["-o", f"{k}:{v}"]
    return args


def run_tshark(pcap: Path, prefs: list[str]) -> tuple[dict[int, dict], str]:
    """Run tshark once; return {frame number: layers} and the raw output text."""
    cmd = [TSHARK, "-n", "-r", str(pcap), "-X", f"lua_script:{LUA}", *prefs, "-T", "json", "-x", "--no-duplicate-keys"]
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, f"tshark failed ({proc.returncode}): {proc.stderr}"
    # tshark prints the "running as root" note on stderr; anything Lua-ish is a failure
    assert "Lua" not in proc.stderr and "lua" not in proc.stderr, proc.stderr
    packets = {}
    for pkt in json.loads(proc.stdout):
        layers = pkt["_source"]["layers"]
        packets[int(layers["frame"]["frame.number"])] = layers
    return packets, proc.stdout + proc.stderr


def as_list(x) -> list:
    if x is None:
        return []
    return x if isinstance(x, list) else [x]


def isight_frames(layers: dict) -> list[dict]:
    return [f for f in as_list(layers.get("isight")) if isinstance(f, dict)]


def expert_messages(node, prefixes=ISIGHT_EXPERTS) -> list[str]:
    """Messages of the isight expert items anywhere below node."""
    found = []
    if isinstance(node, dict):
        for k, v in node.items():
            if k == "_ws.expert":
                for e in as_list(v):
                    if isinstance(e, dict) and any(p in e for p in prefixes):
                        found += as_list(e.get("_ws.expert.message"))
            else:
                found += expert_messages(v, prefixes)
    elif isinstance(node, list):
        for v in node:
            found += expert_messages(v, prefixes)
    return found


# ------------------------------------------------------------------------------------
# comparisons
# ------------------------------------------------------------------------------------
def f32(x) -> float:
    """A vector float (number or "NaN"/"Infinity"/"-Infinity") rounded to binary32."""
    x = float(x) if isinstance(x, str) else x  # float() understands NaN / Infinity / -Infinity
    return struct.unpack(">f", struct.pack(">f", x))[0]


def check_float(layers_obj: dict, field: str, expected, where: str) -> None:
    want = f32(expected)
    shown = layers_obj[field]
    raw_hex = layers_obj[field + "_raw"][0]
    assert len(raw_hex) == 8, f"{where}: {field} is not 4 bytes: {raw_hex}"
    got = struct.unpack(">f", bytes.fromhex(raw_hex))[0]
    if math.isnan(want):
        assert math.isnan(got) and shown.lower() == "nan", f"{where}: {field} = {shown} ({raw_hex}), want NaN"
        return
    assert got == want, f"{where}: {field} bytes {raw_hex} = {got!r}, want {want!r}"
    # the displayed value (tshark prints FT_FLOAT with 6 significant digits)
    shown_f = float(shown)
    if math.isinf(want):
        assert shown_f == want, f"{where}: {field} shows {shown}, want {want}"
    else:
        assert math.isclose(shown_f, want, rel_tol=1e-5, abs_tol=1e-37), (
            f"{where}: {field} shows {shown}, want {want!r}"
        )


def check_frame(obj: dict, frame: dict, where: str) -> None:
    """Every header and block field of one dissected frame equals the vector's frame."""
    for key, field in HEADER_FIELDS.items():
        assert field in obj, f"{where}: {field} missing"
        assert int(obj[field], 0) == frame[key], f"{where}: {field} = {obj[field]}, want {frame[key]:#x}"
    blocks = as_list(obj.get("isight.block"))
    assert len(blocks) == len(frame["blocks"]), f"{where}: {len(blocks)} blocks dissected, want {len(frame['blocks'])}"
    for i, (b, want) in enumerate(zip(blocks, frame["blocks"])):
        bw = f"{where} block {i}"
        assert int(b["isight.block.index"]) == want["index"], (
            f"{bw}: index {b['isight.block.index']}, want {want['index']}"
        )
        if "pose" in want:
            for field, v in zip(POSE_FIELDS, want["pose"], strict=True):
                check_float(b, field, v, bw)
        elif "tolerance" in want:
            check_float(b, "isight.tolerance", want["tolerance"], bw)
        elif "value" in want:
            assert int(b["isight.value"]) == want["value"], f"{bw}: value {b['isight.value']}, want {want['value']}"
        else:
            pytest.fail(f"{bw}: unknown block kind {want}")


def assert_clean(text: str, what: str) -> None:
    for bad in ("Malformed Packet", "_ws.malformed", "Lua Error", "_ws.lua.error"):
        assert bad not in text, f"{what}: tshark output contains {bad!r}"


# ------------------------------------------------------------------------------------
# pcaps
# ------------------------------------------------------------------------------------
def build_group_pcap(path: Path, group: dict) -> dict[int, int]:
    """One connection/datagram per vector; returns {tcId: frame number of its payload}."""
    packets, where = [], {}
    robot_to_box = group["direction"] == "robot-to-box"
    for i, t in enumerate(group["tests"]):
        data = bytes.fromhex(t["hex"])
        client_port = 20000 + i
        if group["transport"] == "tcp":
            conn = TcpConnection(client_port, SERVER_PORT)
            if data:
                conn.send(data, from_client=robot_to_box)
            packets += conn.packets
        else:
            sport, dport = (client_port, SERVER_PORT) if robot_to_box else (SERVER_PORT, client_port)
            packets.append(udp_datagram(data, sport, dport))
        where[t["tcId"]] = len(packets)  # frame numbers start at 1
    write_pcap(path, packets)
    return where


# ------------------------------------------------------------------------------------
# tests
# ------------------------------------------------------------------------------------
def test_dissector_loads():
    proc = subprocess.run(
        [TSHARK, "-G", "protocols", "-X", f"lua_script:{LUA}"], capture_output=True, text=True, timeout=60
    )
    assert proc.returncode == 0, proc.stderr
    assert any(line.split("\t")[-1] == "isight" for line in proc.stdout.splitlines()), "protocol isight not registered"
    assert "Lua" not in proc.stderr, proc.stderr
    fields = subprocess.run(
        [TSHARK, "-G", "fields", "-X", f"lua_script:{LUA}"], capture_output=True, text=True, timeout=60
    ).stdout
    names = {line.split("\t")[2] for line in fields.splitlines() if line.startswith("F\t")}
    required = (
        set(HEADER_FIELDS.values())
        | set(POSE_FIELDS)
        | {"isight.block.index", "isight.tolerance", "isight.value", "isight.crc_status", "isight.crc_computed"}
    )
    assert required <= names, f"missing fields: {sorted(required - names)}"
    heur = subprocess.run(
        [TSHARK, "-G", "heuristic-decodes", "-X", f"lua_script:{LUA}"], capture_output=True, text=True, timeout=60
    ).stdout
    enabled = {tuple(line.split("\t")[:3]) for line in heur.splitlines()}
    assert ("tcp", "isight", "T") in enabled and ("udp", "isight", "T") in enabled, "heuristics not enabled by default"


def test_vector_files_present():
    assert GROUPS, f"no golden vectors in {VECTOR_DIR}"
    assert any(t["result"] == "valid" for _, g in GROUPS for t in g["tests"])


@pytest.mark.parametrize("gid,group", GROUPS, ids=[g[0] for g in GROUPS])
def test_vector_group(gid, group, tmp_path):
    profile = group.get("profile") or {}
    pcap = tmp_path / "group.pcap"
    where = build_group_pcap(pcap, group)
    packets, _ = run_tshark(
        pcap, _prefs(group["crc"], profile.get("crcByteOrder", "big"), profile.get("firstIndex", 0))
    )
    udp = group["transport"] == "udp"
    checked = {"valid": 0, "acceptable": 0, "invalid-flagged": 0, "invalid-unseen": 0}
    for t in group["tests"]:
        what = f"{gid} tcId {t['tcId']} ({t['comment'][:60]})"
        layers = packets[where[t["tcId"]]]
        frames = isight_frames(layers)
        if t["result"] in ("valid", "acceptable"):
            assert_clean(json.dumps(layers), what)
            assert len(frames) == 1, f"{what}: {len(frames)} iSight frames dissected"
            check_frame(frames[0], t["frame"], what)
            if udp:
                assert frames[0]["isight.crc_status"] == "good", f"{what}: CRC {frames[0]['isight.crc_status']}"
            if t["result"] == "valid":
                msgs = expert_messages(layers)
                assert not msgs, f"{what}: expert info on a valid vector: {msgs}"
            else:
                # acceptable = a SHOULD-level deviation: a warning at most, never an error
                errors = expert_messages(layers, ERROR_EXPERTS)
                assert not errors, f"{what}: error-level expert info on an acceptable vector: {errors}"
                for clause in set(t["clauses"]) & WARN_ON_ACCEPTABLE:
                    warned = expert_messages(layers, ("isight.warning",))
                    assert any(f"[{clause}]" in m for m in warned), f"{what}: no [{clause}] warning: {warned}"
            checked[t["result"]] += 1
        else:
            assert "Lua Error" not in json.dumps(layers), f"{what}: Lua error"
            if not frames:
                # e.g. a TCP frame cut short: the dissector waits for the rest, as it must
                assert not (set(t["clauses"]) & MUST_FLAG), f"{what}: {t['clauses']} vector not dissected"
                checked["invalid-unseen"] += 1
                continue
            msgs = expert_messages(layers)
            assert msgs, f"{what}: no expert info on an invalid vector"
            cited = [c for c in t["clauses"] if any(f"[{c}]" in m for m in msgs)]
            assert cited, f"{what}: expert info {msgs} names none of {t['clauses']}"
            checked["invalid-flagged"] += 1
    assert checked["valid"] + checked["acceptable"] + checked["invalid-flagged"] > 0
    print(f"{gid}: {checked}")


def test_tcp_reassembly_split_and_coalesced(tmp_path):
    """One frame over 3 segments, three frames in one segment (R3, R4)."""
    frames = {
        t["hex"]: t["frame"]
        for _, g in GROUPS
        if g["transport"] == "tcp" and not g.get("profile") and g["direction"] == "robot-to-box"
        for t in g["tests"]
        if t["result"] == "valid"
    }
    assert len(frames) >= 3, "need three valid robot-to-box TCP vectors"
    longest = max(frames, key=len)
    three = sorted(frames, key=len)[-3:]
    whole = bytes.fromhex(longest)
    a, b = len(whole) // 3, 2 * len(whole) // 3
    pieces = (whole[:a], whole[a:b], whole[b:])
    coalesced = b"".join(bytes.fromhex(h) for h in three)

    # on 9004, and on a port only the heuristic knows (its first segment has the header)
    conn, heur = TcpConnection(31000, SERVER_PORT), TcpConnection(31001, HEUR_TCP_PORT)
    for c in (conn, heur):
        for piece in pieces:
            c.send(piece)
        c.send(coalesced)
    split_frame_no, three_frame_no = len(conn.packets) - 1, len(conn.packets)
    base = len(conn.packets)
    # R3 down to one byte per segment (the port dissector; a heuristic needs 5 bytes)
    bytewise = TcpConnection(31002, SERVER_PORT)
    for i in range(len(whole)):
        bytewise.send(whole[i : i + 1])
    write_pcap(tmp_path / "reasm.pcap", conn.packets + heur.packets + bytewise.packets)
    packets, text = run_tshark(tmp_path / "reasm.pcap", _prefs())
    assert_clean(text, "reassembly")

    for offset in (0, base):
        for n in (split_frame_no - 2, split_frame_no - 1):
            assert not isight_frames(packets[offset + n]), "frame shown before its last segment"
        got = isight_frames(packets[offset + split_frame_no])
        assert len(got) == 1
        check_frame(got[0], frames[longest], "3-segment frame")
        got = isight_frames(packets[offset + three_frame_no])
        assert len(got) == 3, f"{len(got)} frames in the coalesced segment"
        for obj, h in zip(got, three):
            check_frame(obj, frames[h], "coalesced frame")
        assert not expert_messages(packets[offset + three_frame_no])
    last = len(packets)
    shown = [n for n in range(base + len(heur.packets) + 1, last + 1) if isight_frames(packets[n])]
    assert shown == [last], f"byte-by-byte frame shown in frames {shown}, want only the last ({last})"
    check_frame(isight_frames(packets[last])[0], frames[longest], "byte-by-byte frame")


def test_heuristic_on_other_ports(tmp_path):
    """TCP and UDP frames on ports that are not 9004 (nor the preference ports)."""
    tcp_vectors = [
        (t["hex"], t["frame"])
        for _, g in GROUPS
        if g["transport"] == "tcp" and not g.get("profile")
        for t in g["tests"]
        if t["result"] == "valid"
    ]
    udp_vectors = [
        (t["hex"], t["frame"])
        for _, g in GROUPS
        if g["transport"] == "udp" and not g.get("profile") and g["crc"] == "modbus"
        for t in g["tests"]
        if t["result"] == "valid"
    ]
    assert tcp_vectors and udp_vectors
    packets, where = [], []
    for i, (h, frame) in enumerate(tcp_vectors):
        conn = TcpConnection(32000 + i, HEUR_TCP_PORT)
        conn.send(bytes.fromhex(h), from_client=frame["transferType"] == 1)
        packets += conn.packets
        where.append((len(packets), frame, h))
    for i, (h, frame) in enumerate(udp_vectors):
        packets.append(udp_datagram(bytes.fromhex(h), 33000 + i, HEUR_UDP_PORT))
        where.append((len(packets), frame, h))
    # once the heuristic claimed a connection, later frames on it are ours even when
    # their header is damaged (version 00 02, which the heuristic alone would refuse)
    conn = TcpConnection(32999, HEUR_TCP_PORT)
    conn.send(bytes.fromhex(tcp_vectors[0][0]), from_client=tcp_vectors[0][1]["transferType"] == 1)
    conn.send(bytes.fromhex("fefe000201010000000000000000"))
    packets += conn.packets
    damaged_no = len(packets)
    write_pcap(tmp_path / "heur.pcap", packets)
    # the port preferences moved away as well, so only the heuristics can decode
    dissected, _ = run_tshark(tmp_path / "heur.pcap", _prefs(extra={"isight.tcp_port": "0", "isight.udp_port": "0"}))
    assert any("[F2]" in m for m in expert_messages(dissected[damaged_no])), "damaged frame after the heuristic"
    for n, layers in dissected.items():
        if n != damaged_no:  # an F2 expert (group Malformed) marks its packet malformed
            assert_clean(json.dumps(layers), f"heuristic, frame {n}")
    for n, frame, h in where:
        got = isight_frames(dissected[n])
        assert len(got) == 1, f"heuristic did not decode {h}"
        check_frame(got[0], frame, f"heuristic {h}")


def test_heuristic_can_be_disabled(tmp_path):
    """The heuristics are named isight_tcp and isight_udp (Lua: <proto>_<list>)."""
    udp_hex, tcp_hex = _valid_hex("udp")[0], _valid_hex("tcp", "robot-to-box")[0]
    conn = TcpConnection(34001, HEUR_TCP_PORT)
    conn.send(bytes.fromhex(tcp_hex))
    write_pcap(tmp_path / "h.pcap", [udp_datagram(bytes.fromhex(udp_hex), 34000, HEUR_UDP_PORT)] + conn.packets)
    packets, _ = run_tshark(tmp_path / "h.pcap", [])
    assert isight_frames(packets[1]) and isight_frames(packets[5])
    packets, _ = run_tshark(tmp_path / "h.pcap", ["--disable-heuristic", "isight_udp"])
    assert not isight_frames(packets[1]) and isight_frames(packets[5])
    packets, _ = run_tshark(tmp_path / "h.pcap", ["--disable-heuristic", "isight_tcp"])
    assert isight_frames(packets[1]) and not isight_frames(packets[5])


def test_udp_crc_every_crcmod_algorithm(tmp_path):
    """The Lua CRC-16 agrees with crcmod for every predefined 16-bit algorithm (and byte order)."""
    bodies = [
        bytes.fromhex("fefe00010101000000000000"),
        bytes.fromhex("fefe0001012301010019000000") + struct.pack(">6f", 1.5, -2.25, 1e6, 0.1, -0.0, 3.14159),
    ]
    algorithms = crc16_names()
    assert {"modbus", "xmodem", "kermit", "crc-16", "x-25", "crc-ccitt-false", "crc-16-usb"} <= set(algorithms)
    jobs = []
    for alg in algorithms:
        fn = crcmod.predefined.mkPredefinedCrcFun(alg)
        # the byte order is independent of the algorithm: little-endian for a few only
        for order in ("big", "little") if alg in ("modbus", "x-25", "xmodem") else ("big",):
            pkts = []
            for body in bodies:
                crc = fn(body)
                pkts.append(udp_datagram(body + crc.to_bytes(2, order), 35000, SERVER_PORT))
                pkts.append(udp_datagram(body + (crc ^ 0x0100).to_bytes(2, order), 35000, SERVER_PORT))
            path = tmp_path / f"crc-{alg}-{order}.pcap"
            write_pcap(path, pkts)
            jobs.append((alg, order, path, [fn(b) for b in bodies]))

    def run(job):
        alg, order, path, crcs = job
        return job, run_tshark(path, _prefs(alg, order))[0]

    with ThreadPoolExecutor(max_workers=4) as pool:
        for (alg, order, _, crcs), packets in pool.map(run, jobs):
            for k, crc in enumerate(crcs):
                good, bad = isight_frames(packets[2 * k + 1])[0], isight_frames(packets[2 * k + 2])[0]
                assert good["isight.crc_status"] == "good", f"{alg}/{order}: {good}"
                assert int(good["isight.crc_computed"], 16) == crc, f"{alg}/{order}"
                # isight.check is the wire value read big-endian (as the vectors' frame.check)
                wire = int.from_bytes(crc.to_bytes(2, order), "big")
                assert int(good["isight.check"], 16) == wire, f"{alg}/{order}: check {good['isight.check']}"
                assert bad["isight.crc_status"] == "bad", f"{alg}/{order}: corrupted CRC accepted"
                assert any("[F7]" in m for m in expert_messages(bad)), f"{alg}/{order}: no expert info on a bad CRC"


def test_udp_crc_custom_parameters(tmp_path):
    """The 'custom' algorithm: CRC-16/MODBUS spelled out as parameters."""
    body = bytes.fromhex("fefe00010101000000000000")
    crc = crcmod.predefined.mkPredefinedCrcFun("modbus")(body)
    write_pcap(tmp_path / "c.pcap", [udp_datagram(body + crc.to_bytes(2, "big"), 35000, SERVER_PORT)])
    extra = {
        "isight.crc_custom_poly": "0x8005",
        "isight.crc_custom_init": "ffff",
        "isight.crc_custom_refin": "TRUE",
        "isight.crc_custom_refout": "TRUE",
        "isight.crc_custom_xorout": "0",
    }
    packets, _ = run_tshark(tmp_path / "c.pcap", _prefs("custom", extra=extra))
    assert isight_frames(packets[1])[0]["isight.crc_status"] == "good"
    extra["isight.crc_custom_init"] = "0"  # now it is CRC-16/ARC: must not match
    packets, _ = run_tshark(tmp_path / "c.pcap", _prefs("custom", extra=extra))
    assert isight_frames(packets[1])[0]["isight.crc_status"] == "bad"


def test_oversize_header_and_garbage(tmp_path):
    """R5: a header announcing 255×65535 bytes is flagged at once, not waited for.
    R6: garbage before a frame is skipped and the frame after it decodes."""
    ok = bytes.fromhex("fefe000101010000000000000000")  # CycleOn
    oversize = bytes.fromhex("fefe0001012301ffffff0000") + bytes(30)
    c1 = TcpConnection(36000, SERVER_PORT)
    c1.send(oversize)
    c2 = TcpConnection(36001, SERVER_PORT)
    c2.send(b"\x00garbage\xfe" + ok + ok)
    write_pcap(tmp_path / "r.pcap", c1.packets + c2.packets)
    packets, _ = run_tshark(tmp_path / "r.pcap", _prefs())
    msgs = expert_messages(packets[4])
    assert any("[R5]" in m for m in msgs), msgs
    frames = isight_frames(packets[8])
    assert any("[F1]" in m and "R6" in m for m in expert_messages(packets[8]))
    decoded = [f for f in frames if "isight.action" in f]
    assert len(decoded) == 2 and all(int(f["isight.action"], 0) == 1 for f in decoded)


def test_header_with_a_bad_version_is_skipped_like_the_codec_does(tmp_path):
    """F2/R6: a header whose version is not 00 01 is not trusted for framing; the frames
    after it decode (the codec's stream decoder and the reference box skip it too)."""
    bad = bytes.fromhex("fefe00810127000000000000") + b"\x00"
    none = bytes.fromhex("fefe000101000000000000000000")
    pose = bytes.fromhex("fefe0001012301010019000000") + bytes(24) + b"\x00\x00"
    c = TcpConnection(37000, SERVER_PORT)
    c.send(bad + none)
    c.send(pose)
    write_pcap(tmp_path / "v.pcap", c.packets)
    packets, _ = run_tshark(tmp_path / "v.pcap", _prefs())
    decoded = [f for p in packets.values() for f in isight_frames(p) if "isight.action" in f]
    actions = [int(f["isight.action"], 0) for f in decoded]
    assert actions == [0x00, 0x23], actions
    msgs = [m for p in packets.values() for m in expert_messages(p)]
    assert any("[F2]" in m and "R6" in m for m in msgs), msgs
    assert not any("[F3]" in m or "[A5]" in m or "[B5]" in m for m in msgs), msgs

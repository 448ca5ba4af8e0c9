"""Pcap proof of a suite run: every pcap the run writes is what happened on the sockets.

A representative subset of the conformance suite (frame, block, action, robustness,
UDP, extension, timing, scripted and fuzz cases) runs in-process against the bundled
box with ``--pcap-dir``; a collector plugin keeps each case's socket transcript. Then
every pcap is read by tshark with the Lua dissector, the box's port set as the iSight
server port, and:

* tshark and the dissector raise no Lua error (stderr, ``_ws.lua.error``);
* TCP analysis flags nothing: no retransmission, lost segment, out-of-order, duplicate
  ACK, window problem (no ``tcp.analysis.flags`` on any packet);
* per TCP connection and direction, the segments' sequence numbers run on without a
  gap and their payload, in order, equals the transcript's bytes byte for byte; for a
  few reassembly-heavy cases (one byte per segment, 64 KiB sends, coalesced frames)
  Wireshark's own stream reassembly (``-z follow,tcp,raw``) is compared too;
* per UDP socket, the datagrams equal the transcript's, in order;
* a packet whose bytes belong only to *valid* frames (as the codec decodes the
  transcript) carries no malformed marker (``_ws.malformed``) and no iSight error
  expert: the dissector flags deliberately malformed frames, and only those (a fuzz
  pcap must show some flagged ones, so the dissector is seen to be at work). The
  dissector frames the stream exactly as the codec does, resynchronisation included.

Skipped only when tshark is missing.
"""

from __future__ import annotations

import os
import shutil
import subprocess
from collections import defaultdict
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest

from conformance.harness.transcript import Kind, Transcript
from conformance.protocol import Frame, ProtocolError, StreamDecoder, TransferType, decode_datagram
from conformance.pytest_plugin import CTX

ROOT = Path(__file__).resolve().parents[2]
LUA = ROOT / "conformance" / "wireshark" / "isight.lua"
TSHARK = shutil.which("tshark")
CASES = [
    "F1-*", "F3-02", "F5-*", "F6-*", "F7-*", "B1-01", "B3-02", "B4-*", "A1-01", "R2-*", "R3-*", "R4-*", "R5-01",
    "R7-*", "S5-01", "T2-01", "E2-01", "SEQ-R3", "FUZZ-01",
]
#: Cases whose streams are also compared with Wireshark's own reassembly (-z follow).
FOLLOW = ("R3-01", "R3-02", "R4-01", "R2-01", "B1-01", "A1-01", "SEQ-R3")
#: Streams compared with Wireshark's own reassembly, and bytes compared with the transcripts.
COMPARED = {"followed": 0, "bytes": 0}
FIELDS = ("frame.number", "tcp.stream", "tcp.srcport", "tcp.dstport", "udp.srcport", "udp.dstport", "tcp.seq",
          "tcp.nxtseq", "tcp.payload", "udp.payload", "tcp.analysis.flags", "_ws.malformed", "_ws.lua.error",
          "isight.malformed", "isight.protocol", "isight.bad_crc", "tcp.flags.syn")

pytestmark = [
    pytest.mark.tshark,
    pytest.mark.skipif(TSHARK is None, reason="tshark is not installed (apt-get install tshark)"),
    pytest.mark.timeout(240),
]


class Collector:
    """Keeps every case's context (its transcript and pcap path) after the case's teardown."""

    def __init__(self) -> None:
        self.contexts: dict[str, Any] = {}

    @pytest.hookimpl(hookwrapper=True)
    def pytest_runtest_teardown(self, item: pytest.Item) -> Any:
        yield
        ctx = item.stash.get(CTX, None)
        if ctx is not None and ctx.pcap is not None:
            self.contexts[ctx.info.id] = ctx


@dataclass
class Run:
    contexts: dict[str, Any]
    tcp_port: int
    udp_port: int


@pytest.fixture(scope="module")
def run(tmp_path_factory: pytest.TempPathFactory) -> Run:
    d = tmp_path_factory.mktemp("suite")
    collector = Collector()
    args = ["-c", os.devnull, "--rootdir", str(d), "--pyargs", "conformance.cases", "-p", "no:cacheprovider",
            "-p", "no:terminal", "--pcap-dir", str(d / "pcaps"), "--stream-seconds", "0.5"]
    for glob in CASES:
        args += ["--cases", glob]
    code = pytest.main(args, plugins=[collector])
    assert code in (0, 1), f"the suite run ended with pytest exit code {code}"
    assert len(collector.contexts) > 50, sorted(collector.contexts)
    any_ctx = next(iter(collector.contexts.values()))
    udp = any_ctx.session.udp_target()
    return Run(collector.contexts, any_ctx.session.target().port, udp.port if udp else 0)


# -- tshark ------------------------------------------------------------------------------------------


@dataclass
class Packet:
    number: int
    stream: int | None
    sport: int
    dport: int
    udp: bool
    seq: int
    nxtseq: int
    payload: bytes
    analysis: bool
    flagged: bool  # _ws.malformed or an iSight error expert
    lua_error: bool
    syn: bool


def tshark(pcap: Path, tcp_port: int, udp_port: int, *extra: str) -> tuple[str, str]:
    cmd = [TSHARK, "-n", "-r", str(pcap), "-X", f"lua_script:{LUA}", "-o", f"isight.tcp_port:{tcp_port}",
           "-o", f"isight.udp_port:{udp_port}", *extra]
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, f"tshark failed on {pcap.name} ({proc.returncode}): {proc.stderr}"
    return proc.stdout, proc.stderr


def packets(pcap: Path, tcp_port: int, udp_port: int) -> tuple[list[Packet], str]:
    args = ["-T", "fields", "-E", "separator=|", "-E", "occurrence=a"]
    for f in FIELDS:
        args += ["-e", f]
    out, err = tshark(pcap, tcp_port, udp_port, *args)
    found = []
    for line in out.splitlines():
        v = line.split("|")
        if len(v) != len(FIELDS):
            continue
        rec = dict(zip(FIELDS, v))
        udp = bool(rec["udp.srcport"])
        found.append(Packet(
            number=int(rec["frame.number"]),
            stream=int(rec["tcp.stream"]) if rec["tcp.stream"] else None,
            sport=int(rec["udp.srcport"] or rec["tcp.srcport"] or 0),
            dport=int(rec["udp.dstport"] or rec["tcp.dstport"] or 0),
            udp=udp,
            seq=int(rec["tcp.seq"] or 0),
            nxtseq=int(rec["tcp.nxtseq"] or 0),
            payload=bytes.fromhex((rec["udp.payload"] if udp else rec["tcp.payload"]).replace(":", "")),
            analysis=bool(rec["tcp.analysis.flags"]),
            flagged=any(rec[k] for k in ("_ws.malformed", "isight.malformed", "isight.protocol", "isight.bad_crc")),
            lua_error=bool(rec["_ws.lua.error"]),
            syn=rec["tcp.flags.syn"] in ("1", "True"),
        ))
    return found, err


def followed(pcap: Path, tcp_port: int, udp_port: int, streams: list[int]) -> dict[int, tuple[bytes, bytes]]:
    """Wireshark's reassembled stream (client→server, server→client) per tcp.stream."""
    args = ["-q"]
    for s in streams:
        args += ["-z", f"follow,tcp,raw,{s}"]
    out, _ = tshark(pcap, tcp_port, udp_port, *args)
    result: dict[int, tuple[bytes, bytes]] = {}
    blocks = out.split("===================================================================")
    for block in blocks:
        lines = block.strip().splitlines()
        if not lines or not lines[0].startswith("Follow: tcp,raw"):
            continue
        filters = [line for line in lines if line.startswith("Filter: tcp.stream eq ")]
        if not filters:
            continue
        stream = int(filters[0].rsplit(" ", 1)[1])
        client, server = bytearray(), bytearray()
        for line in lines[1:]:
            if line.startswith(("Filter:", "Node ")) or not line.strip():
                continue
            (server if line.startswith("\t") else client).extend(bytes.fromhex(line.strip()))
        result[stream] = (bytes(client), bytes(server))
    return result


# -- the transcript side ------------------------------------------------------------------------------


def transcript_streams(tr: Transcript) -> dict[int, dict[str, Any]]:
    """conn id -> {transport, port (ours), sent, received, datagrams}."""
    out: dict[int, dict[str, Any]] = {}
    for info in tr.connections.values():
        out[info.conn] = {"transport": info.transport, "port": info.local.port, "sent": bytearray(),
                          "received": bytearray(), "datagrams": []}
    for ev in tr.events:
        c = out.get(ev.conn)
        if c is None or ev.kind not in (Kind.SEND, Kind.RECV):
            continue
        (c["sent"] if ev.kind == Kind.SEND else c["received"]).extend(ev.data)
        c["datagrams"].append((ev.kind, ev.data))
    return out


def frame_ranges(data: bytes, expect: TransferType, profile: Any) -> list[tuple[int, int, bool]]:
    """(start, end, valid) of every decoder event of a byte stream."""
    decoder = StreamDecoder(profile, expect)
    ranges = []
    decoder.receive_data(data) if data else None
    while True:
        start = decoder.offset
        event = decoder.next_event()
        if not isinstance(event, (Frame, ProtocolError)):
            break
        ranges.append((start, decoder.offset, isinstance(event, Frame)))
    if decoder.buffered:
        ranges.append((decoder.offset, len(data), False))
    return ranges


def only_valid(ranges: list[tuple[int, int, bool]], lo: int, hi: int) -> bool:
    touched = [valid for start, end, valid in ranges if start < hi and end > lo]
    return bool(touched) and all(touched)


# -- the checks ----------------------------------------------------------------------------------------


def check_case(case_id: str, ctx: Any, run: Run) -> list[str]:
    """Everything wrong with one case's pcap (empty: all good)."""
    problems: list[str] = []
    pcap = Path(ctx.pcap)
    pkts, err = packets(pcap, run.tcp_port, run.udp_port)
    noise = [line for line in err.splitlines() if "Running as user" not in line and line.strip()]
    if any("lua" in line.lower() for line in noise):
        problems.append(f"tshark/Lua said: {noise}")
    problems += [f"frame {p.number}: Lua error in the dissector" for p in pkts if p.lua_error]
    problems += [f"frame {p.number}: TCP analysis flags it" for p in pkts if p.analysis]
    conns = transcript_streams(ctx.transcript)
    profile = ctx.profile
    by_stream: dict[int, list[Packet]] = defaultdict(list)
    udp_by_port: dict[int, list[Packet]] = defaultdict(list)
    for p in pkts:
        if p.udp:
            udp_by_port[p.sport if p.dport == run.udp_port else p.dport].append(p)
        elif p.stream is not None:
            by_stream[p.stream].append(p)
    # TCP: map each stream to the transcript connection with that client port (in order, for a reused port)
    tcp_conns: dict[int, list[dict[str, Any]]] = defaultdict(list)
    for c in conns.values():
        if c["transport"] == "tcp":
            tcp_conns[c["port"]].append(c)
    follow: list[int] = []
    mapped: dict[int, dict[str, Any]] = {}
    for stream, plist in sorted(by_stream.items()):
        client = plist[0].sport if plist[0].dport == run.tcp_port else plist[0].dport
        candidates = tcp_conns.get(client, [])
        if not candidates:
            problems.append(f"tcp.stream {stream}: client port {client} is not in the transcript")
            continue
        conn = candidates.pop(0)
        mapped[stream] = conn
        for out, expect in ((True, TransferType.ROBOT_TO_BOX), (False, TransferType.BOX_TO_ROBOT)):
            want = bytes(conn["sent"] if out else conn["received"])
            seg = [p for p in plist if (p.dport == run.tcp_port) == out and p.payload]
            got = b"".join(p.payload for p in seg)
            where = f"tcp.stream {stream} ({'robot→box' if out else 'box→robot'})"
            if got != want:
                problems.append(f"{where}: payload {len(got)} bytes differs from the transcript's {len(want)} bytes")
            COMPARED["bytes"] += len(want)
            offset = 1
            for p in seg:
                if p.seq != offset:
                    problems.append(f"{where} frame {p.number}: seq {p.seq}, expected {offset}")
                offset = p.nxtseq
            ranges = frame_ranges(want, expect, profile)
            for p in seg:
                if not (p.flagged and only_valid(ranges, p.seq - 1, p.nxtseq - 1)):
                    continue
                problems.append(f"{where} frame {p.number}: flagged malformed, but its bytes are valid frames")
        if case_id.split("[")[0] in FOLLOW and (conn["sent"] or conn["received"]):
            follow.append(stream)
    for c in conns.values():
        if c["transport"] == "tcp" and (c["sent"] or c["received"]) and c not in mapped.values():
            problems.append(f"transcript connection on port {c['port']} with data has no tcp.stream in the pcap")
    # UDP: datagrams in order per socket
    for c in conns.values():
        if c["transport"] != "udp":
            continue
        got = [(p.dport == run.udp_port, p.payload) for p in sorted(udp_by_port.get(c["port"], []), key=lambda p: p.number)]
        want = [(kind == Kind.SEND, data) for kind, data in c["datagrams"]]
        if got != want:
            problems.append(f"UDP port {c['port']}: {len(got)} datagrams differ from the transcript's {len(want)}")
        for p in udp_by_port.get(c["port"], []):
            expect = TransferType.ROBOT_TO_BOX if p.dport == run.udp_port else TransferType.BOX_TO_ROBOT
            try:
                decode_datagram(p.payload, profile, expect)
            except ProtocolError:
                continue
            if p.flagged:
                problems.append(f"UDP frame {p.number}: flagged malformed, but it is a valid datagram")
    # Wireshark's own reassembly of the streams that stress it
    if follow:
        for stream, (client, server) in followed(pcap, run.tcp_port, run.udp_port, follow[:40]).items():
            conn = mapped[stream]
            COMPARED["followed"] += 1
            if client != bytes(conn["sent"]) or server != bytes(conn["received"]):
                problems.append(f"tcp.stream {stream}: Wireshark's reassembled stream differs from the transcript")
    return problems


def test_every_pcap_is_the_transcript(run: Run) -> None:
    with ThreadPoolExecutor(max_workers=2) as pool:
        results = dict(zip(run.contexts, pool.map(lambda cid: check_case(cid, run.contexts[cid], run), run.contexts)))
    bad = {cid: problems[:5] for cid, problems in results.items() if problems}
    assert not bad, bad
    assert COMPARED["followed"] >= 10 and COMPARED["bytes"] > 100_000, COMPARED


def test_the_dissector_flags_malformed_frames_in_the_fuzz_pcap(run: Run) -> None:
    ctx = run.contexts["FUZZ-01"]
    pkts, _ = packets(Path(ctx.pcap), run.tcp_port, run.udp_port)
    flagged = [p for p in pkts if p.flagged]
    # (at least ten: 21 were flagged when eight suites shared two cores, hundreds on a quiet machine)
    assert len(flagged) >= 10, "the fuzz case sent malformed frames: the dissector should flag many packets"
    # FUZZ-01 runs for two seconds, so how many examples fit depends on the machine's load: every example's
    # bytes (and its probe) are in the pcap, so there are at least as many payload packets as examples
    examples = ctx.details["fuzz"]["examples"]
    assert examples >= 20 and sum(1 for p in pkts if p.payload) >= examples, examples  # 50 at load 7, 8 workers

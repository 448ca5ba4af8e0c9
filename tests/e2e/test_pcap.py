"""Per-case pcapng evidence (conformance/evidence/pcap.py), proven on real loopback traffic.

A tiny iSight box (TCP + UDP, answers every request 0000, closes after a CycleOff)
runs on 127.0.0.1 (and ::1 when the host has IPv6). Plain sockets talk to it and
every connect / sendall / recv / close is recorded in a Transcript with a PcapRecorder
attached, so the pcapng is written while the traffic runs. Two cases:

* PCAP-001: ping, one frame in 3 sends, 50 frames coalesced in one send, close; a
  connection the box closes; one we abort (RST); a refused connect; UDP datagrams;
  an IPv6 connection.
* PCAP-002: a 10,000-pose burst in one send (split into 65,000-byte segments).

tshark with the project's Lua dissector then checks each file: no malformed packets,
Lua errors or iSight errors, no TCP analysis flag at all (retransmission, lost
segment, ACKed unseen segment, out of order, ...), the payload per direction equals
the transcript's bytes, the iSight PDU count per direction equals the frames sent and
received, every packet is the one the transcript implies (time stamp to the
microsecond, direction, flags, length), and comments carry the case ID and steps.
Further: the file is readable while the recorder is open and after its process is
killed, write_transcript gives the same bytes as live recording, and scapy agrees
with every header and checksum.

The tshark tests are skipped only when tshark is not installed.
"""

from __future__ import annotations

import json
import os
import shutil
import signal
import socket
import struct
import subprocess
import sys
import threading
import zlib
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from decimal import Decimal
from pathlib import Path

import pytest

from conformance.evidence.pcap import MAX_SEGMENT, PcapRecorder, write_transcript
from conformance.harness.transcript import Endpoint, Kind, Transcript
from conformance.protocol import (
    CLOSED,
    NEED_DATA,
    Action,
    Frame,
    StreamDecoder,
    TransferType,
    answer,
    decode_datagram,
    encode_tcp,
    encode_udp,
    pose_blocks,
    request,
    tolerance_blocks,
)

ROOT = Path(__file__).resolve().parents[2]
LUA = Path(os.environ.get("ISIGHT_DISSECTOR", ROOT / "conformance" / "wireshark" / "isight.lua"))
TSHARK = shutil.which("tshark")
IO_TIMEOUT = 10.0  # seconds a socket call may block before the test fails (never hit)
BURST = 10_000

needs_tshark = [
    pytest.mark.tshark,
    pytest.mark.skipif(TSHARK is None, reason="tshark is not installed (apt-get install tshark)"),
]

# Every flag of Wireshark's TCP analysis is a failure here: the synthesised stream is
# a perfect one. (The brief's list, and the rest of tcp.analysis.flags.)
BAD_TCP = (
    "tcp.analysis.retransmission",
    "tcp.analysis.spurious_retransmission",
    "tcp.analysis.fast_retransmission",
    "tcp.analysis.lost_segment",
    "tcp.analysis.ack_lost_segment",
    "tcp.analysis.out_of_order",
    "tcp.analysis.duplicate_ack",
    "tcp.analysis.zero_window",
    "tcp.analysis.window_full",
    "tcp.analysis.flags",
)
BAD_OTHER = ("_ws.malformed", "_ws.lua.error", "isight.malformed", "isight.protocol", "isight.bad_crc")


# ------------------------------------------------------------------------------------
# a tiny iSight box
# ------------------------------------------------------------------------------------
class Box:
    """Answers every decoded request with a 0000 answer; closes a TCP connection right
    after answering a CycleOff. TCP and UDP on the same port number when possible."""

    def __init__(self, host: str = "127.0.0.1") -> None:
        family = socket.AF_INET6 if ":" in host else socket.AF_INET
        self.host = host
        self.stopping = threading.Event()
        self.threads: list[threading.Thread] = []
        for _ in range(20):  # bounded: find a port free for both TCP and UDP
            tcp = socket.socket(family, socket.SOCK_STREAM)
            tcp.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
            tcp.bind((host, 0))
            port = tcp.getsockname()[1]
            udp = socket.socket(family, socket.SOCK_DGRAM)
            try:
                udp.bind((host, port))
            except OSError:
                tcp.close()
                udp.close()
                continue
            break
        else:  # pragma: no cover
            raise RuntimeError("no port free for both TCP and UDP")
        tcp.listen(16)
        tcp.settimeout(0.2)
        udp.settimeout(0.2)
        self.tcp, self.udp, self.port = tcp, udp, port
        self._spawn(self._accept_loop)
        self._spawn(self._udp_loop)

    def _spawn(self, target, *args) -> None:
        t = threading.Thread(target=target, args=args, daemon=True)
        t.start()
        self.threads.append(t)

    def _accept_loop(self) -> None:
        while not self.stopping.is_set():
            try:
                conn, _ = self.tcp.accept()
            except TimeoutError:
                continue
            except OSError:
                return
            self._spawn(self._serve, conn)

    def _serve(self, conn: socket.socket) -> None:
        conn.settimeout(IO_TIMEOUT)
        decoder = StreamDecoder(expect=TransferType.ROBOT_TO_BOX)
        with conn:
            while not self.stopping.is_set():
                try:
                    data = conn.recv(1 << 20)
                except OSError:
                    return
                if not data:
                    return
                decoder.receive_data(data)
                out, close = [], False
                while (event := decoder.next_event()) is not NEED_DATA:
                    if isinstance(event, Frame):
                        out.append(encode_tcp(answer(event.action)))
                        if event.action == Action.CYCLE_OFF:
                            close = True
                            break
                try:
                    if out:
                        conn.sendall(b"".join(out))
                except OSError:
                    return
                if close:
                    return

    def _udp_loop(self) -> None:
        while not self.stopping.is_set():
            try:
                data, peer = self.udp.recvfrom(65536)
            except TimeoutError:
                continue
            except OSError:
                return
            try:
                frame = decode_datagram(data, expect=TransferType.ROBOT_TO_BOX)
            except Exception:  # noqa: BLE001 - a bad datagram is dropped (R7)
                continue
            self.udp.sendto(encode_udp(answer(frame.action)), peer)

    def close(self) -> None:
        self.stopping.set()
        self.tcp.close()
        self.udp.close()
        for t in self.threads:
            t.join(timeout=2)


# ------------------------------------------------------------------------------------
# a recorded client (plain sockets)
# ------------------------------------------------------------------------------------
@dataclass
class Tally:
    """What one connection carried, counted on our side of the socket."""

    sent: list[int] = field(default_factory=list)  # actions of the frames we sent
    received: list[int] = field(default_factory=list)  # actions of the answers we decoded


class Client:
    def __init__(self, tr: Transcript, host: str, port: int, label: str, rcvbuf: int | None = None) -> None:
        family = socket.AF_INET6 if ":" in host else socket.AF_INET
        sock = socket.socket(family, socket.SOCK_STREAM)
        if rcvbuf:
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, rcvbuf)
        sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        sock.settimeout(IO_TIMEOUT)
        sock.connect((host, port))
        local, remote = sock.getsockname(), sock.getpeername()
        self.tr, self.sock, self.tally = tr, sock, Tally()
        self.info = tr.open("tcp", Endpoint(local[0], local[1]), Endpoint(remote[0], remote[1]), label)
        tr.add(self.info.conn, Kind.CONNECT, note=f"{label} connected")
        self.decoder = StreamDecoder(expect=TransferType.BOX_TO_ROBOT)

    def send(self, data: bytes, note: str = "", actions: list[int] | None = None) -> None:
        self.sock.sendall(data)
        self.tr.add(self.info.conn, Kind.SEND, data, note)
        self.tally.sent += actions or []

    def send_frames(self, frames: list[Frame], note: str = "") -> None:
        self.send(b"".join(encode_tcp(f) for f in frames), note, [int(f.action) for f in frames])

    def expect(self, n: int) -> None:
        """Receive (and record each recv of) the next ``n`` answers."""
        want = len(self.tally.received) + n
        for _ in range(1_000_000):  # bounded; each recv blocks at most IO_TIMEOUT
            while (event := self.decoder.next_event()) is not NEED_DATA:
                assert isinstance(event, Frame), f"the box sent something undecodable: {event}"
                self.tally.received.append(int(event.action))
            if len(self.tally.received) >= want:
                assert len(self.tally.received) == want
                return
            data = self.sock.recv(1 << 20)
            assert data, "the box closed the connection early"
            self.tr.add(self.info.conn, Kind.RECV, data)
            self.decoder.receive_data(data)

    def expect_eof(self) -> None:
        data = self.sock.recv(1 << 16)
        assert data == b"", f"expected the box to close, got {data!r}"
        self.tr.add(self.info.conn, Kind.PEER_CLOSE)

    def close(self, note: str = "") -> None:
        self.sock.shutdown(socket.SHUT_WR)
        self.tr.add(self.info.conn, Kind.CLOSE, note=note)

    def release(self) -> None:
        self.sock.close()

    def abort(self, note: str = "") -> None:
        self.sock.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, struct.pack("ii", 1, 0))
        self.tr.add(self.info.conn, Kind.ABORT, note=note)
        self.sock.close()


def pose(i: int) -> Frame:
    return request(Action.POSE, pose_blocks([(1000.0 + i, -250.5, 300.25, 180.0, -0.5, 90.0 + i / 1000)]))


def ipv6_loopback() -> bool:
    if not socket.has_ipv6:
        return False
    try:
        with socket.socket(socket.AF_INET6, socket.SOCK_STREAM) as s:
            s.bind(("::1", 0))
    except OSError:
        return False
    return True


@dataclass
class Case:
    case_id: str
    transcript: Transcript
    pcap: Path
    tallies: dict[int, Tally]  # conn -> frames sent / answers received
    udp: dict[int, Tally]
    prefs: list[str]
    expected_comments: list[str]


def run_mixed_case(out: Path) -> Case:
    case_id = "PCAP-001"
    tr = Transcript(case_id=case_id)
    pcap = out / f"{case_id}.pcapng"
    PcapRecorder.attach(tr, pcap)
    box = Box("127.0.0.1")
    box6 = Box("::1") if ipv6_loopback() else None
    tallies: dict[int, Tally] = {}
    udp_tallies: dict[int, Tally] = {}
    try:
        # 1: ping, one frame in 3 sends, 50 frames in one send, then a clean close
        c = Client(tr, "127.0.0.1", box.port, "command")
        tr.note("liveness probe", c.info.conn)
        c.send_frames([request(Action.NONE)], "ping")
        c.expect(1)
        cycle_on = encode_tcp(request(Action.CYCLE_ON))
        for i, (a, b) in enumerate(((0, 1), (1, 12), (12, len(cycle_on)))):
            c.send(cycle_on[a:b], f"CycleOn piece {i + 1}/3", [Action.CYCLE_ON] if i == 2 else [])
        c.expect(1)
        c.send_frames([pose(i) for i in range(50)], "50 poses coalesced in one send")
        c.expect(50)
        c.send_frames([request(Action.TOLERANCE, tolerance_blocks([0.5, 1.5]))], "tolerance")
        c.expect(1)
        c.close("disconnect")
        c.expect_eof()
        c.release()
        tallies[c.info.conn] = c.tally

        # 2: the box closes after CycleOff; then we close our side
        c = Client(tr, "127.0.0.1", box.port, "closed-by-box")
        c.send_frames([request(Action.CYCLE_OFF)], "CycleOff")
        c.expect(1)
        c.expect_eof()
        c.close()
        c.release()
        tallies[c.info.conn] = c.tally

        # 3: we reset the connection
        c = Client(tr, "127.0.0.1", box.port, "aborted")
        c.send_frames([request(Action.NONE)], "ping before abort")
        c.expect(1)
        c.abort("abort (RST)")
        tallies[c.info.conn] = c.tally

        # 4: a refused connect (a port nobody listens on)
        probe = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        probe.bind(("127.0.0.1", 0))
        dead_port = probe.getsockname()[1]
        probe.close()
        s = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        s.bind(("127.0.0.1", 0))
        local = s.getsockname()
        info = tr.open("tcp", Endpoint(*local), Endpoint("127.0.0.1", dead_port), "refused")
        with pytest.raises(ConnectionRefusedError) as refused:
            s.settimeout(IO_TIMEOUT)
            s.connect(("127.0.0.1", dead_port))
        s.close()
        tr.add(info.conn, Kind.CONNECT_FAILED, note=f"connection refused ({refused.value.strerror})")
        tallies[info.conn] = Tally()

        # 5: UDP datagrams
        u = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        u.settimeout(IO_TIMEOUT)
        u.connect(("127.0.0.1", box.port))
        info = tr.open("udp", Endpoint(*u.getsockname()), Endpoint(*u.getpeername()), "udp")
        tally = udp_tallies[info.conn] = Tally()
        for i, frame in enumerate([request(Action.NONE), request(Action.CYCLE_ON), pose(7)]):
            data = encode_udp(frame)
            u.send(data)
            tr.add(info.conn, Kind.SEND, data, f"datagram {i + 1}")
            tally.sent.append(int(frame.action))
            reply = u.recv(65536)
            tr.add(info.conn, Kind.RECV, reply)
            tally.received.append(int(decode_datagram(reply, expect=TransferType.BOX_TO_ROBOT).action))
        u.close()

        # 6: IPv6
        if box6 is not None:
            c = Client(tr, "::1", box6.port, "ipv6")
            c.send_frames([request(Action.NONE), pose(1)], "ping + pose over IPv6")
            c.expect(2)
            c.close()
            c.expect_eof()
            c.release()
            tallies[c.info.conn] = c.tally
    finally:
        tr.close()
        box.close()
        if box6 is not None:
            box6.close()
    prefs = ["-o", f"isight.tcp_port:{box.port}", "-o", f"isight.udp_port:{box.port}"]
    if box6 is not None:
        prefs += ["-o", f"isight.tcp_port_extra:{box6.port}"]
    expected = [
        f"{case_id}: liveness probe",
        f"{case_id}: ping",
        f"{case_id}: CycleOn piece 2/3",
        f"{case_id}: 50 poses coalesced in one send",
        f"{case_id}: disconnect",
        f"{case_id}: abort (RST)",
        f"{case_id}: datagram 3",
    ]
    return Case(case_id, tr, pcap, tallies, udp_tallies, prefs, expected)


def run_burst_case(out: Path) -> Case:
    case_id = "PCAP-002"
    tr = Transcript(case_id=case_id)
    pcap = out / f"{case_id}.pcapng"
    PcapRecorder.attach(tr, pcap)
    box = Box("127.0.0.1")
    try:
        # a receive buffer for all 140,000 answer bytes: the box's answers can never
        # block it while our one big sendall is still going
        c = Client(tr, "127.0.0.1", box.port, "stream", rcvbuf=1 << 20)
        c.send_frames([pose(i) for i in range(BURST)], f"{BURST}-pose burst")
        c.expect(BURST)
        c.close("Send_Pos_Off")
        c.expect_eof()
        c.release()
    finally:
        tr.close()
        box.close()
    prefs = ["-o", f"isight.tcp_port:{box.port}"]
    return Case(case_id, tr, pcap, {c.info.conn: c.tally}, {}, prefs, [f"{case_id}: {BURST}-pose burst"])


def tally_from_transcript(tr: Transcript, conn: int) -> Tally:
    """Frames sent and answers received on a TCP connection, decoded from the transcript."""
    tally = Tally()
    for data, expect, into in (
        (tr.sent(conn), TransferType.ROBOT_TO_BOX, tally.sent),
        (tr.received(conn), TransferType.BOX_TO_ROBOT, tally.received),
    ):
        decoder = StreamDecoder(expect=expect)
        decoder.receive_data(data)  # b"" (nothing sent) reads as end of stream: fine
        while (event := decoder.next_event()) not in (NEED_DATA, CLOSED):
            assert isinstance(event, Frame), event
            into.append(int(event.action))
    return tally


def run_harness_case(out: Path) -> Case:
    """The same evidence from the suite's own recorded client (conformance.harness.client)."""
    from conformance.harness.client import Answer, Closed, TcpConnection, UdpChannel
    from conformance.harness.target import Target, Unreachable
    from conformance.protocol import DEFAULT_PROFILE

    case_id = "PCAP-003"
    tr = Transcript(case_id=case_id)
    pcap = out / f"{case_id}.pcapng"
    PcapRecorder.attach(tr, pcap)
    box = Box("127.0.0.1")
    target = Target("127.0.0.1", box.port)
    try:
        conn = TcpConnection(tr, target, DEFAULT_PROFILE, "command").connect()
        assert isinstance(conn.request(request(Action.NONE), "ping"), Answer)
        frame = encode_tcp(request(Action.CYCLE_ON))
        assert conn.send_pieces([frame[:3], frame[3:9], frame[9:]], note="CycleOn")
        assert isinstance(conn.next_outcome(), Answer)
        assert isinstance(conn.request(request(Action.CYCLE_OFF), "CycleOff"), Answer)
        assert isinstance(conn.next_outcome(), Closed)  # the box closes after CycleOff
        conn.close("disconnect")
        probe = socket.socket()
        probe.bind(("127.0.0.1", 0))
        dead = Target("127.0.0.1", probe.getsockname()[1])
        probe.close()
        with pytest.raises(Unreachable):
            TcpConnection(tr, dead, DEFAULT_PROFILE, "refused").connect()
        udp = UdpChannel(tr, target, DEFAULT_PROFILE)
        assert isinstance(udp.request(request(Action.NONE), "udp ping"), Answer)
        udp.sock.close()
    finally:
        tr.close()
        box.close()
    tallies = {c: tally_from_transcript(tr, c) for c, i in tr.connections.items() if i.transport == "tcp"}
    udp_tallies = {c: Tally([0], [0]) for c, i in tr.connections.items() if i.transport == "udp"}
    prefs = ["-o", f"isight.tcp_port:{box.port}", "-o", f"isight.udp_port:{box.port}"]
    expected = [f"{case_id}: ping", f"{case_id}: CycleOn piece 1/3", f"{case_id}: disconnect", f"{case_id}: udp ping"]
    return Case(case_id, tr, pcap, tallies, udp_tallies, prefs, expected)


# ------------------------------------------------------------------------------------
# tshark
# ------------------------------------------------------------------------------------
FIELDS = (
    "frame.number",
    "frame.interface_id",
    "frame.time_epoch",
    "frame.comment",
    "frame.protocols",
    "tcp.stream",
    "udp.stream",
    "tcp.srcport",
    "tcp.dstport",
    "udp.srcport",
    "udp.dstport",
    "tcp.flags",
    "tcp.len",
    "tcp.payload",
    "udp.payload",
    "isight.transfer_type",
    "isight.action",
)


@dataclass
class TsharkView:
    packets: list[dict]
    flagged: str  # frames matching any BAD_* field (should be empty)
    stderr: str


def tshark(args: list[str]) -> subprocess.CompletedProcess:
    assert TSHARK is not None
    proc = subprocess.run([TSHARK, "-n", *args], capture_output=True, text=True, timeout=120)
    return proc


def lua_problems(stderr: str) -> list[str]:
    return [line for line in stderr.splitlines() if "lua" in line.lower() or "error" in line.lower()]


def view(case: Case) -> TsharkView:
    base = ["-r", str(case.pcap), "-X", f"lua_script:{LUA}", *case.prefs]
    fields = [a for f in FIELDS for a in ("-e", f)]
    with ThreadPoolExecutor(2) as pool:
        f_json = pool.submit(tshark, [*base, "-T", "json", *fields])
        f_bad = pool.submit(
            tshark,
            [*base, "-Y", " || ".join(BAD_TCP + BAD_OTHER), "-T", "fields", "-e", "frame.number", "-e", "_ws.col.Info"],
        )
        pj, pb = f_json.result(), f_bad.result()
    for p in (pj, pb):
        assert p.returncode == 0, f"tshark failed ({p.returncode}): {p.stderr}"
    packets = [pkt["_source"]["layers"] for pkt in json.loads(pj.stdout)]
    return TsharkView(packets, pb.stdout, pj.stderr + pb.stderr)


@pytest.fixture(scope="module")
def cases(tmp_path_factory) -> dict[str, Case]:
    out = tmp_path_factory.mktemp("pcap")
    runs = {"mixed": run_mixed_case, "burst": run_burst_case, "harness": run_harness_case}
    with ThreadPoolExecutor(len(runs)) as pool:
        futures = {name: pool.submit(run, out) for name, run in runs.items()}
        return {name: f.result() for name, f in futures.items()}


@pytest.fixture(scope="module")
def views(cases) -> dict[str, TsharkView]:
    if TSHARK is None:
        pytest.skip("tshark is not installed (apt-get install tshark)")
    with ThreadPoolExecutor(len(cases)) as pool:
        futures = {name: pool.submit(view, case) for name, case in cases.items()}
        return {name: f.result() for name, f in futures.items()}


def local_port(info) -> int:
    """The local port a connection has in the file: a failed connect that never got one
    is drawn from 61000 + conn (pcap.py; outside Linux's ephemeral range)."""
    return info.local.port or 61000 + info.conn % 4500


def port_map(tr: Transcript) -> dict[int, int]:
    return {local_port(i): c for c, i in tr.connections.items()}


def one(layers: dict, key: str, default=None):
    v = layers.get(key)
    return v[0] if v else default


def epoch_us(text: str) -> int:
    return int(Decimal(text) * 1_000_000)


# ------------------------------------------------------------------------------------
# what the transcript implies, packet by packet (the oracle, from the brief)
# ------------------------------------------------------------------------------------
SYN, ACK, FIN, RST, PSH = 0x02, 0x10, 0x01, 0x04, 0x08


def implied_packets(tr: Transcript) -> list[tuple[int, int, bool, int | None, int]]:
    """(conn, time in us, from us?, TCP flags or None for UDP, payload length) per packet."""
    out = []
    for ev in tr.events:
        info = tr.connections.get(ev.conn)
        if info is None or ev.kind == Kind.NOTE:
            continue
        us = round(ev.t * 1_000_000)

        def add(mine: bool, flags: int | None, size: int = 0, conn: int = ev.conn, us: int = us) -> None:
            out.append((conn, us, mine, flags, size))

        if info.transport == "udp":
            if ev.kind in (Kind.SEND, Kind.RECV):
                add(ev.kind == Kind.SEND, None, len(ev.data))
            continue
        if ev.kind == Kind.CONNECT:
            add(True, SYN)
            add(False, SYN | ACK)
            add(True, ACK)
        elif ev.kind == Kind.CONNECT_FAILED:
            add(True, SYN)
            if "refused" in ev.note:
                add(False, RST | ACK)
        elif ev.kind in (Kind.SEND, Kind.RECV):
            mine = ev.kind == Kind.SEND
            sizes = [min(MAX_SEGMENT, len(ev.data) - i) for i in range(0, len(ev.data), MAX_SEGMENT)]
            for k, size in enumerate(sizes):
                add(mine, ACK | (PSH if k == len(sizes) - 1 else 0), size)
                add(not mine, ACK)
        elif ev.kind in (Kind.CLOSE, Kind.PEER_CLOSE):
            mine = ev.kind == Kind.CLOSE
            add(mine, FIN | ACK)
            add(not mine, ACK)
        elif ev.kind in (Kind.ABORT, Kind.PEER_RESET):
            add(ev.kind == Kind.ABORT, RST | ACK)
    return out


# ------------------------------------------------------------------------------------
# the tshark proofs
# ------------------------------------------------------------------------------------
CASE_NAMES = ["mixed", "burst", "harness"]


@pytest.mark.parametrize("name", CASE_NAMES)
class TestTshark:
    pytestmark = needs_tshark

    def test_no_malformed_lua_errors_or_tcp_analysis_flags(self, views, name):
        v = views[name]
        assert v.flagged.strip() == "", f"frames flagged by tshark:\n{v.flagged[:3000]}"
        assert not lua_problems(v.stderr), v.stderr
        assert all("_ws.malformed" not in one(p, "frame.protocols", "") for p in v.packets)

    def test_every_packet_is_the_one_the_transcript_implies(self, cases, views, name):
        case, v = cases[name], views[name]
        want = implied_packets(case.transcript)
        got = []
        ports = {c: port for port, c in port_map(case.transcript).items()}
        for p in v.packets:
            if one(p, "frame.interface_id") != "0":
                continue
            us = epoch_us(one(p, "frame.time_epoch"))
            if "tcp.srcport" in p:
                sport, dport = int(one(p, "tcp.srcport")), int(one(p, "tcp.dstport"))
                flags, size = int(one(p, "tcp.flags"), 16), int(one(p, "tcp.len"))
            else:
                sport, dport = int(one(p, "udp.srcport")), int(one(p, "udp.dstport"))
                flags, size = None, len(bytes.fromhex(one(p, "udp.payload", "").replace(":", "")))
            conn = next(c for c, port in ports.items() if port in (sport, dport))
            got.append((conn, us, sport == ports[conn], flags, size))
        assert len(got) == len(want), f"{len(got)} packets in the file, the transcript implies {len(want)}"
        for i, (g, w) in enumerate(zip(got, want)):
            assert g == w, f"packet {i + 1}: got (conn, us, ours, flags, len) = {g}, want {w}"

    def test_payload_per_direction_equals_the_transcript(self, cases, views, name):
        case, v = cases[name], views[name]
        streams: dict[tuple[int, bool], bytearray] = {}
        datagrams: dict[tuple[int, bool], list[bytes]] = {}
        ports = port_map(case.transcript)
        for p in v.packets:
            if "tcp.srcport" in p:
                sport, dport = int(one(p, "tcp.srcport")), int(one(p, "tcp.dstport"))
                ours = sport in ports
                conn = ports[sport if ours else dport]
                streams.setdefault((conn, ours), bytearray()).extend(bytes.fromhex(one(p, "tcp.payload", "")))
            elif "udp.srcport" in p:
                sport, dport = int(one(p, "udp.srcport")), int(one(p, "udp.dstport"))
                ours = sport in ports
                conn = ports[sport if ours else dport]
                datagrams.setdefault((conn, ours), []).append(bytes.fromhex(one(p, "udp.payload", "")))
        tr = case.transcript
        for conn, info in tr.connections.items():
            if info.transport == "tcp":
                assert bytes(streams.get((conn, True), b"")) == tr.sent(conn), f"conn {conn}: bytes we sent differ"
                assert bytes(streams.get((conn, False), b"")) == tr.received(conn), (
                    f"conn {conn}: bytes received differ"
                )
            else:
                want_out = [e.data for e in tr.events if e.conn == conn and e.kind == Kind.SEND]
                want_in = [e.data for e in tr.events if e.conn == conn and e.kind == Kind.RECV]
                assert datagrams.get((conn, True), []) == want_out
                assert datagrams.get((conn, False), []) == want_in

    def test_isight_pdus_equal_frames_sent_and_received(self, cases, views, name):
        case, v = cases[name], views[name]
        ports = port_map(case.transcript)
        seen: dict[tuple[int, int], list[int]] = {}
        for p in v.packets:
            proto = "tcp" if "tcp.srcport" in p else "udp" if "udp.srcport" in p else None
            if proto is None:
                continue
            sport, dport = int(one(p, f"{proto}.srcport")), int(one(p, f"{proto}.dstport"))
            conn = ports[sport] if sport in ports else ports[dport]
            tts = [int(x, 0) for x in p.get("isight.transfer_type", [])]
            actions = [int(x, 0) for x in p.get("isight.action", [])]
            assert len(tts) == len(actions)
            for tt, action in zip(tts, actions):
                seen.setdefault((conn, tt), []).append(action)
        total_frames = 0
        for conn, tally in {**case.tallies, **case.udp}.items():
            assert seen.get((conn, 0x01), []) == tally.sent, f"conn {conn}: iSight requests tshark found"
            assert seen.get((conn, 0x10), []) == tally.received, f"conn {conn}: iSight answers tshark found"
            total_frames += len(tally.sent) + len(tally.received)
        assert sum(len(a) for a in seen.values()) == total_frames
        if name == "burst":
            assert total_frames == 2 * BURST

    def test_comments_carry_case_id_and_steps(self, cases, views, name):
        case, v = cases[name], views[name]
        comments = [c for p in v.packets for c in p.get("frame.comment", [])]
        assert comments, "no packet comments"
        assert all(c.startswith(f"{case.case_id}: ") for c in comments), comments
        for want in case.expected_comments:
            assert want in comments, f"{want!r} not among the comments {comments}"
        n_conns = len(case.transcript.connections)
        described = [c for c in comments if c.startswith(f"{case.case_id}: conn ")]
        assert len(described) == n_conns  # each connection says once which it is


@pytest.mark.tshark
@pytest.mark.skipif(TSHARK is None, reason="tshark is not installed (apt-get install tshark)")
def test_burst_is_split_into_max_segment_segments(cases, views):
    sent = BURST * len(encode_tcp(pose(0)))
    port = next(iter(cases["burst"].transcript.connections.values())).local.port
    lens = [int(one(p, "tcp.len")) for p in views["burst"].packets if one(p, "tcp.srcport") == str(port)]
    lens = [n for n in lens if n]
    assert lens == [min(MAX_SEGMENT, sent - i) for i in range(0, sent, MAX_SEGMENT)]


@pytest.mark.tshark
@pytest.mark.skipif(TSHARK is None, reason="tshark is not installed (apt-get install tshark)")
def test_reassembled_follow_stream_equals_transcript(cases):
    """tshark's own reassembly (follow tcp raw) of the burst equals the transcript."""
    case = cases["burst"]
    proc = tshark(["-r", str(case.pcap), "-q", "-z", "follow,tcp,raw,0"])
    assert proc.returncode == 0, proc.stderr
    body = proc.stdout.split("===================================================================")[1]
    lines = [ln for ln in body.splitlines()[5:] if ln.strip()]
    client = b"".join(bytes.fromhex(ln) for ln in lines if not ln.startswith("\t"))
    server = b"".join(bytes.fromhex(ln.strip()) for ln in lines if ln.startswith("\t"))
    conn = next(iter(case.tallies))
    assert client == case.transcript.sent(conn)
    assert server == case.transcript.received(conn)


# ------------------------------------------------------------------------------------
# the same bytes, after the fact; scapy agrees with every header
# ------------------------------------------------------------------------------------
@pytest.mark.parametrize("name", CASE_NAMES)
def test_write_transcript_equals_live_recording(cases, tmp_path, name):
    case = cases[name]
    again = write_transcript(case.transcript, tmp_path / "again.pcapng")
    assert again.read_bytes() == case.pcap.read_bytes()


def test_scapy_agrees_with_every_header_and_checksum(cases):
    from scapy.layers.inet import IP, TCP, UDP
    from scapy.layers.inet6 import IPv6
    from scapy.layers.l2 import Ether
    from scapy.utils import rdpcap

    packets = rdpcap(str(cases["mixed"].pcap))
    checked = 0
    for pkt in packets:
        if not isinstance(pkt, Ether):
            continue
        rebuilt = Ether(bytes(pkt))
        for layer in (IP, TCP, UDP):
            if layer in rebuilt:
                for fld in ("chksum", "len", "dataofs"):
                    if fld in rebuilt[layer].fields:
                        delattr(rebuilt[layer], fld)
        if IPv6 in rebuilt:
            del rebuilt[IPv6].plen
        assert bytes(rebuilt) == bytes(pkt), f"scapy rebuilds packet {checked + 1} differently:\n{pkt.show2(dump=True)}"
        checked += 1
    assert checked >= 50
    # and the comments survive a round trip through scapy's pcapng reader
    assert any(b"PCAP-001: liveness probe" in c for p in packets for c in (getattr(p, "comments", None) or []))


def test_struct_headers_equal_scapy_construction(tmp_path):
    """The fast struct path builds exactly what scapy's Ether()/IP()/TCP()/Raw builds."""
    from scapy.layers.inet import IP, TCP, UDP
    from scapy.layers.inet6 import IPv6
    from scapy.layers.l2 import Ether
    from scapy.packet import Raw
    from scapy.utils import rdpcap

    tr = Transcript(case_id="S-1", clock=iter(1_700_000_000.5 + i for i in range(100)).__next__)
    pcap = tmp_path / "s.pcapng"
    PcapRecorder.attach(tr, pcap)
    c = tr.open("tcp", Endpoint("127.0.0.1", 40001), Endpoint("127.0.0.1", 9004), "cmd")
    tr.add(c.conn, Kind.CONNECT)
    tr.add(c.conn, Kind.SEND, encode_tcp(request(Action.NONE)) + b"x")  # odd length
    u = tr.open("udp", Endpoint("::1", 40002), Endpoint("::1", 9004), "udp")
    tr.add(u.conn, Kind.SEND, encode_udp(request(Action.NONE)))
    tr.close()
    got = [bytes(p) for p in rdpcap(str(pcap))]
    zero = "00:00:00:00:00:00"
    payload = encode_tcp(request(Action.NONE)) + b"x"
    isn, isn_remote = zlib.crc32(b"S-1/1/local"), zlib.crc32(b"S-1/1/remote")
    eth4 = Ether(src=zero, dst=zero, type=0x0800)
    ip4 = dict(src="127.0.0.1", dst="127.0.0.1", flags="DF", ttl=64)
    want_syn = (
        eth4
        / IP(id=0, **ip4)
        / TCP(sport=40001, dport=9004, flags="S", seq=isn, window=65535, options=[("MSS", 65495)])
    )
    want_data = (
        eth4
        / IP(id=2, **ip4)
        / TCP(sport=40001, dport=9004, flags="PA", seq=isn + 1, ack=isn_remote + 1, window=65535)
        / Raw(payload)
    )
    want_udp = (
        Ether(src=zero, dst=zero, type=0x86DD)
        / IPv6(src="::1", dst="::1", hlim=64)
        / UDP(sport=40002, dport=9004)
        / Raw(encode_udp(request(Action.NONE)))
    )
    assert got[0] == bytes(want_syn)
    assert got[3] == bytes(want_data)
    assert got[5] == bytes(want_udp)


# ------------------------------------------------------------------------------------
# interrupted runs leave readable files
# ------------------------------------------------------------------------------------
@pytest.mark.tshark
@pytest.mark.skipif(TSHARK is None, reason="tshark is not installed (apt-get install tshark)")
def test_readable_while_the_recorder_is_open(tmp_path):
    tr = Transcript(case_id="OPEN-1")
    rec = PcapRecorder.attach(tr, tmp_path / "open.pcapng")
    c = tr.open("tcp", Endpoint("127.0.0.1", 40003), Endpoint("127.0.0.1", 9004), "cmd")
    tr.add(c.conn, Kind.CONNECT)
    counts = []
    for round_ in range(3):
        for i in range(10):
            tr.add(c.conn, Kind.SEND, encode_tcp(pose(i)), f"round {round_} pose {i}")
            tr.add(c.conn, Kind.RECV, encode_tcp(answer(Action.POSE)))
        proc = tshark(
            [
                "-r",
                str(rec.path),
                "-X",
                f"lua_script:{LUA}",
                "-T",
                "fields",
                "-e",
                "isight.action",
                "-E",
                "occurrence=a",
            ]
        )
        assert proc.returncode == 0 and not lua_problems(proc.stderr), proc.stderr
        lines = proc.stdout.splitlines()
        assert len(lines) == rec.packets  # every packet written so far, nothing half-written
        counts.append(sum(1 for ln in lines if ln))
    assert counts == [20, 40, 60]
    assert not rec.closed
    tr.close()


KILL_SCRIPT = r"""
import sys
from conformance.harness.transcript import Endpoint, Kind, Transcript
from conformance.evidence.pcap import PcapRecorder
from conformance.protocol import Action, encode_tcp, pose_blocks, request
tr = Transcript(case_id="KILL-1")
rec = PcapRecorder.attach(tr, sys.argv[1])
c = tr.open("tcp", Endpoint("127.0.0.1", 40004), Endpoint("127.0.0.1", 9004), "stream")
tr.add(c.conn, Kind.CONNECT)
frame = encode_tcp(request(Action.POSE, pose_blocks([(1, 2, 3, 4, 5, 6)])))
big = frame * 4000
for i in range(2_000_000):  # bounded; the test kills us long before
    tr.add(c.conn, Kind.SEND, big if i % 50 == 0 else frame, f"pose {i}")
    if i % 200 == 0:
        print(rec.packets, flush=True)
"""


@pytest.mark.tshark
@pytest.mark.skipif(TSHARK is None, reason="tshark is not installed (apt-get install tshark)")
def test_readable_after_the_writer_is_killed(tmp_path):
    path = tmp_path / "killed.pcapng"
    proc = subprocess.Popen([sys.executable, "-c", KILL_SCRIPT, str(path)], stdout=subprocess.PIPE, text=True, cwd=ROOT)
    try:
        reported = 0
        for _ in range(10_000):  # bounded by lines; each comes within milliseconds
            line = proc.stdout.readline()
            assert line, f"the writer exited early ({proc.poll()})"
            reported = int(line)
            if reported >= 5000:
                break
        os.kill(proc.pid, signal.SIGKILL)  # wherever it is: between events or inside a write
    finally:
        proc.wait(timeout=30)
        proc.stdout.close()
    result = tshark(["-r", str(path), "-T", "fields", "-e", "frame.number", "-e", "tcp.len"])
    if result.returncode != 0:  # only acceptable failure: the kill landed inside the last write
        assert "cut short in the middle of a packet" in result.stderr, result.stderr
    numbers = [int(ln.split("\t")[0]) for ln in result.stdout.splitlines() if ln]
    assert len(numbers) >= reported, f"{len(numbers)} packets readable, {reported} were written before the kill"
    assert numbers == list(range(1, len(numbers) + 1))


# ------------------------------------------------------------------------------------
# transcripts the loopback tests cannot produce
# ------------------------------------------------------------------------------------
def synthetic(case_id: str = "SYN-1") -> Transcript:
    times = iter(1_700_000_000.000001 + i * 0.001 for i in range(1000))
    return Transcript(case_id=case_id, clock=times.__next__)


@pytest.mark.tshark
@pytest.mark.skipif(TSHARK is None, reason="tshark is not installed (apt-get install tshark)")
def test_edge_cases_show_in_tshark(tmp_path):
    tr = synthetic()
    pcap = tmp_path / "edge.pcapng"
    PcapRecorder.attach(tr, pcap)
    # a connect that timed out: a lone SYN
    c1 = tr.open("tcp", Endpoint("0.0.0.0", 0), Endpoint("127.0.0.1", 9004), "command")
    tr.add(c1.conn, Kind.CONNECT_FAILED, note="no answer to the connection request within time_out (5000 ms)")
    # an accepted connection (we are the server): the SYN comes from the peer
    c2 = tr.open("tcp", Endpoint("127.0.0.1", 9004), Endpoint("127.0.0.1", 40010), "robot")
    tr.add(c2.conn, Kind.CONNECT, note="accepted robot connection")
    tr.add(c2.conn, Kind.RECV, encode_tcp(request(Action.NONE)))
    tr.add(c2.conn, Kind.SEND, b"", "zero-byte send")  # nothing on the wire; the note moves on
    tr.add(c2.conn, Kind.SEND, encode_tcp(answer(Action.NONE)))
    tr.add(c2.conn, Kind.PEER_RESET, note="Connection reset by peer")
    tr.add(c2.conn, Kind.CLOSE, note="close after the reset")  # nothing on the wire; the note is kept
    # a connection whose events start without a connect (a late listener)
    c3 = tr.open("tcp", Endpoint("127.0.0.1", 40011), Endpoint("127.0.0.1", 9004), "late")
    tr.add(c3.conn, Kind.SEND, encode_tcp(request(Action.CYCLE_ON)), "CycleOn")
    tr.add(c3.conn, Kind.CLOSE)
    tr.note("a note no packet follows", c3.conn)
    tr.close()
    proc = tshark(
        [
            "-r",
            str(pcap),
            "-X",
            f"lua_script:{LUA}",
            "-T",
            "fields",
            "-E",
            "occurrence=a",
            "-E",
            "aggregator=|",
            "-e",
            "frame.interface_id",
            "-e",
            "tcp.srcport",
            "-e",
            "tcp.flags.str",
            "-e",
            "tcp.len",
            "-e",
            "frame.comment",
            "-e",
            "isight.action",
            "-e",
            "text",
        ]
    )
    assert proc.returncode == 0 and not lua_problems(proc.stderr), proc.stderr
    rows = [ln.split("\t") for ln in proc.stdout.splitlines()]
    flags = [r[2].replace("·", "") for r in rows if r[0] == "0"]
    assert flags == [
        "S",  # c1: lone SYN
        "S",
        "AS",
        "A",  # c2 handshake
        "AP",
        "A",  # request from the robot, our ACK
        "AP",
        "A",  # our answer, its ACK
        "AR",  # peer reset
        "S",
        "AS",
        "A",
        "AP",
        "A",
        "AF",
        "A",  # c3: handshake drawn, data, close
    ], rows
    assert rows[1][1] == "40010"  # c2's SYN comes from the robot
    comments = "|".join(r[4] for r in rows)
    assert "SYN-1: no answer to the connection request within time_out (5000 ms)" in comments
    assert "SYN-1: zero-byte send" in rows[6][4]  # moved to the next packet of c2
    assert "SYN-1: handshake not in the transcript; drawn here" in rows[9][4]
    marker = rows[-1]
    assert "SYN-1: close after the reset" in marker[4]
    assert (
        marker[0] == "1" and "SYN-1: a note no packet follows" in marker[4] and "a note no packet follows" in marker[6]
    )
    flagged = tshark(["-r", str(pcap), "-X", f"lua_script:{LUA}", "-Y", " || ".join(BAD_TCP + BAD_OTHER)])
    assert flagged.returncode == 0 and flagged.stdout.strip() == "", flagged.stdout


def test_write_error_never_breaks_the_case(tmp_path, caplog):
    tr = synthetic("ERR-1")
    rec = PcapRecorder.attach(tr, tmp_path / "err.pcapng")

    class Broken:
        def write(self, data):
            raise OSError(28, "No space left on device")

        def close(self):
            pass

    rec._out._file = Broken()  # the disk fills up mid-case
    c = tr.open("tcp", Endpoint("127.0.0.1", 40020), Endpoint("127.0.0.1", 9004))
    tr.add(c.conn, Kind.CONNECT)
    tr.add(c.conn, Kind.SEND, b"x")
    tr.close()
    assert rec.error is not None and rec.error.errno == 28
    assert "No space left" in caplog.text


def test_bad_max_segment_is_refused(tmp_path):
    with pytest.raises(ValueError, match="max_segment"):
        PcapRecorder(tmp_path / "x.pcapng", max_segment=70000)


@pytest.mark.tshark
@pytest.mark.skipif(TSHARK is None, reason="tshark is not installed (apt-get install tshark)")
def test_the_tcp_analysis_check_is_not_vacuous(tmp_path):
    """Drop one data segment from a good file: the same filter must now flag frames."""
    tr = synthetic("NEG-1")
    good = tmp_path / "good.pcapng"
    PcapRecorder.attach(tr, good)
    c = tr.open("tcp", Endpoint("127.0.0.1", 40030), Endpoint("127.0.0.1", 9004), "cmd")
    tr.add(c.conn, Kind.CONNECT)
    for i in range(3):
        tr.add(c.conn, Kind.SEND, encode_tcp(pose(i)))
        tr.add(c.conn, Kind.RECV, encode_tcp(answer(Action.POSE)))
    tr.close()
    raw = good.read_bytes()
    blocks, pos = [], 0
    while pos < len(raw):  # pcapng blocks: type, total length, ..., total length
        size = struct.unpack_from("<I", raw, pos + 4)[0]
        blocks.append(raw[pos : pos + size])
        pos += size
    epbs = [i for i, b in enumerate(blocks) if struct.unpack_from("<I", b)[0] == 6]
    del blocks[epbs[3 + 4]]  # the second pose (after the handshake and the first exchange)
    bad = tmp_path / "bad.pcapng"
    bad.write_bytes(b"".join(blocks))
    flt = " || ".join(BAD_TCP + BAD_OTHER)
    for path, want_flagged in ((good, False), (bad, True)):
        proc = tshark(["-r", str(path), "-X", f"lua_script:{LUA}", "-Y", flt, "-T", "fields", "-e", "frame.number"])
        assert proc.returncode == 0, proc.stderr
        assert bool(proc.stdout.strip()) is want_flagged, (path.name, proc.stdout)


@pytest.mark.parametrize("seed", range(4))
def test_checksums_equal_scapys_including_the_minus_zero_case(seed):
    """The modulo-0xFFFF checksum equals scapy's RFC 1071 one, also when the words sum
    to a multiple of 0xFFFF (checksum 0x0000; a UDP checksum 0 is sent as 0xFFFF)."""
    import random

    from scapy.layers.inet import IP, TCP, UDP
    from scapy.layers.l2 import Ether

    from conformance.evidence import packet_builder as P

    rng = random.Random(seed)
    conn = P.Flow(None, False, bytes([127, 0, 0, 1]), bytes([127, 0, 0, 1]), 40000, 9004, {True: 1, False: 2})  # type: ignore[arg-type]

    def build(proto: str, payload: bytes) -> bytes:
        return P.tcp(conn, True, 0x18, payload=payload) if proto == "tcp" else P.udp(conn, True, payload)

    for size in [0, 1, 2, 3, 39, 1460, 65000] + [rng.randrange(1, 3000) for _ in range(20)]:
        payload = bytes(rng.randrange(256) for _ in range(size))
        for proto in ("tcp", "udp"):
            for fix_sum in (False, True):
                data = payload[: len(payload) & ~1] if fix_sum else payload
                if fix_sum:  # append the checksum of data + 00 00: the words then sum to -0
                    probe = build(proto, data + b"\x00\x00")
                    cs = struct.unpack_from("!H", probe, 14 + 20 + (16 if proto == "tcp" else 6))[0]
                    data += cs.to_bytes(2, "big")
                frame = build(proto, data)
                pkt = Ether(frame)
                layer = pkt[TCP] if proto == "tcp" else pkt[UDP]
                rebuilt = pkt.copy()
                del rebuilt[IP].chksum
                if proto == "tcp":
                    del rebuilt[TCP].chksum
                else:
                    del rebuilt[UDP].chksum
                assert bytes(rebuilt) == frame, (proto, size, fix_sum, hex(layer.chksum))
                if fix_sum:
                    assert layer.chksum == (0 if proto == "tcp" else 0xFFFF), (proto, size, hex(layer.chksum))

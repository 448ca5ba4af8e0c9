"""Captures for the analyze tests: recorded from the suite's own runs, or written by hand.

* :func:`record` runs the bundled reference box and the robot simulator in-process
  (one asyncio loop, loopback only) with a recording proxy between them, and writes
  what passed through the proxy as pcapng (the harness synthesises the packets from
  the socket transcript: :func:`conformance.evidence.pcap.write_transcript`). Box
  knobs (``BoxConfig``), robot faults (``RobotFaults``, ``steps``) and a ``tamper``
  hook on the bytes either way make broken boxes and robots.
* :class:`Capture` writes packets by hand with scapy (explicit MAC addresses, so
  scapy never resolves anything), with correct sequence numbers and ACKs, for the
  cases a real run cannot produce (gaps, reordering, retransmissions, captures that
  start mid-session, mixed traffic).
"""

from __future__ import annotations

import asyncio
import contextlib
from collections.abc import Callable
from pathlib import Path
from typing import Any

from scapy.layers.inet import IP, TCP, UDP
from scapy.layers.inet6 import IPv6
from scapy.layers.l2 import Ether
from scapy.packet import Raw
from scapy.utils import wrpcap, wrpcapng

from conformance.endpoints.behaviour import BoxConfig
from conformance.endpoints.robot import RobotSession
from conformance.endpoints.robot.robot_result import RobotResult
from conformance.endpoints.server import ReferenceBox
from conformance.evidence.pcap import write_transcript
from conformance.harness.transcript import Endpoint, Kind, Transcript
from conformance.protocol import Action, Profile, answer, encode, pose_blocks, request

ROBOT_MAC, BOX_MAC = "02:00:00:00:00:01", "02:00:00:00:00:02"
ROBOT_IP, BOX_IP = "10.0.0.2", "10.0.0.1"
POSE = encode(request(Action.POSE, pose_blocks([(800.0, 10.0, 300.0, 180.0, 0.0, 90.0)])))
POSE_OK = encode(answer(Action.POSE))
FAST = Profile(time_out_ms=1000, vision_time_out_ms=1000)

Tamper = Callable[[str, bytes], bytes]  # (direction "robot" or "box", bytes) -> bytes actually passed on


# -- recorded runs ----------------------------------------------------------------------------------
class _Proxy:
    """Forward each robot connection to the box, recording both directions in one transcript."""

    def __init__(self, box_port: int, tamper: Tamper | None) -> None:
        self.box_port = box_port
        self.tamper = tamper
        self.transcript = Transcript(case_id="analyze-test")
        self.tasks: list[asyncio.Task[None]] = []

    async def handle(self, r_reader: asyncio.StreamReader, r_writer: asyncio.StreamWriter) -> None:
        b_reader, b_writer = await asyncio.open_connection("127.0.0.1", self.box_port)
        peer = r_writer.get_extra_info("peername")
        info = self.transcript.open("tcp", Endpoint(peer[0], peer[1]), Endpoint("127.0.0.1", self.box_port))
        conn = info.conn
        self.transcript.add(conn, Kind.CONNECT)

        async def pump(src: asyncio.StreamReader, dst: asyncio.StreamWriter, side: str) -> None:
            data_kind, close_kind = (Kind.SEND, Kind.CLOSE) if side == "robot" else (Kind.RECV, Kind.PEER_CLOSE)
            try:
                while True:
                    data = await src.read(65536)
                    if not data:
                        self.transcript.add(conn, close_kind)
                        with contextlib.suppress(OSError, RuntimeError):
                            dst.write_eof()
                        return
                    if self.tamper is not None:
                        data = self.tamper(side, data)
                    if data:
                        self.transcript.add(conn, data_kind, data)
                        with contextlib.suppress(OSError, RuntimeError):
                            dst.write(data)
            except (ConnectionError, OSError):
                self.transcript.add(conn, Kind.ABORT if side == "robot" else Kind.PEER_RESET)
                dst.close()

        await asyncio.gather(pump(r_reader, b_writer, "robot"), pump(b_reader, r_writer, "box"))
        for w in (r_writer, b_writer):
            w.close()


async def _record(box: BoxConfig, robots: list[dict[str, Any]], profile: Profile, tamper: Tamper | None,
                  client: Callable[[int], Any] | None) -> tuple[Transcript, list[RobotResult]]:
    async with ReferenceBox(box, host="127.0.0.1", port=0, udp=False) as ref:
        proxy = _Proxy(ref.tcp_port, tamper)
        server = await asyncio.start_server(proxy.handle, "127.0.0.1", 0)
        port = server.sockets[0].getsockname()[1]
        results = []
        async with server:
            for kwargs in robots:
                kwargs = dict(kwargs)
                kwargs.setdefault("duration", 0.6)
                kwargs.setdefault("result_wait", 0.1)
                results.append(await RobotSession(("127.0.0.1", port), profile, **kwargs).run())
            if client is not None:
                await client(port)
            await asyncio.sleep(0.2)  # closes travel through the proxy
        return proxy.transcript, results


def record(path: Path, box: BoxConfig | None = None, robots: list[dict[str, Any]] | None = None,
           profile: Profile = FAST, tamper: Tamper | None = None,
           client: Callable[[int], Any] | None = None) -> tuple[Path, list[RobotResult]]:
    """Run robot sessions (RobotSession keyword arguments each) against the reference box through a
    recording proxy; write what went through it to ``path`` (pcapng). The box side is port 9004."""
    transcript, results = asyncio.run(_record(box or BoxConfig(profile=profile), robots or [{}], profile, tamper,
                                              client))
    # the capture shows the box on 9004, whatever port the proxy had
    for n, info in list(transcript.connections.items()):
        transcript.connections[n] = type(info)(info.conn, info.transport, info.local, Endpoint("127.0.0.1", 9004),
                                               info.label)
    write_transcript(transcript, path)
    return path, results


# -- hand-written packets ---------------------------------------------------------------------------
class Capture:
    """Packets written by hand: ``conn = cap.tcp(port)`` then ``conn.robot(data)``,
    ``conn.box(data)``, ``conn.close()``; ``cap.write(path)``. Time advances by ``step``
    seconds per packet unless given."""

    def __init__(self, t0: float = 1_700_000_000.0, step: float = 0.001, v6: bool = False) -> None:
        self.packets: list[Any] = []
        self.t = t0
        self.step = step
        self.v6 = v6

    def add(self, pkt: Any, t: float | None = None) -> Any:
        self.t = self.t + self.step if t is None else t
        pkt.time = self.t
        self.packets.append(pkt)
        return pkt

    def ip(self, src: str, dst: str) -> Any:
        if self.v6:
            return IPv6(src="fd00::2" if src == ROBOT_IP else "fd00::1" if src == BOX_IP else "fd00::9",
                        dst="fd00::2" if dst == ROBOT_IP else "fd00::1" if dst == BOX_IP else "fd00::9")
        return IP(src=src, dst=dst)

    def frame(self, src: str, dst: str, l4: Any, payload: bytes = b"") -> Any:
        pkt = Ether(src=ROBOT_MAC if src == ROBOT_IP else BOX_MAC, dst=BOX_MAC if src == ROBOT_IP else ROBOT_MAC)
        pkt = pkt / self.ip(src, dst) / l4
        return pkt / Raw(payload) if payload else pkt

    def tcp(self, robot_port: int, box_port: int = 9004, handshake: bool = True, robot_seq: int = 1000,
            box_seq: int = 5000) -> TcpConn:
        return TcpConn(self, robot_port, box_port, handshake, robot_seq, box_seq)

    def udp(self, data: bytes, from_robot: bool = True, robot_port: int = 40000, box_port: int = 9004,
            t: float | None = None) -> Any:
        src, dst = (ROBOT_IP, BOX_IP) if from_robot else (BOX_IP, ROBOT_IP)
        sport, dport = (robot_port, box_port) if from_robot else (box_port, robot_port)
        return self.add(self.frame(src, dst, UDP(sport=sport, dport=dport), data), t)

    def other(self, data: bytes = b"GET / HTTP/1.1\r\n\r\n", port: int = 80) -> Any:
        """Unrelated traffic: a TCP segment between two other hosts' ports."""
        return self.add(Ether(src="02:00:00:00:00:09", dst=BOX_MAC) / IP(src="10.0.0.9", dst=BOX_IP)
                        / TCP(sport=50000, dport=port, flags="PA", seq=1, ack=1) / Raw(data))

    def write(self, path: Path, fmt: str = "pcapng", packets: list[Any] | None = None) -> Path:
        (wrpcapng if fmt == "pcapng" else wrpcap)(str(path), packets if packets is not None else self.packets)
        return path


class TcpConn:
    def __init__(self, cap: Capture, robot_port: int, box_port: int, handshake: bool, robot_seq: int,
                 box_seq: int) -> None:
        self.cap, self.rport, self.bport = cap, robot_port, box_port
        self.seq = {True: robot_seq, False: box_seq}
        if handshake:
            self.segment(True, "S", b"", seq=robot_seq, ack=0)
            self.segment(False, "SA", b"", seq=box_seq, ack=robot_seq + 1)
            self.seq = {True: robot_seq + 1, False: box_seq + 1}
            self.segment(True, "A", b"")

    def segment(self, from_robot: bool, flags: str, data: bytes, seq: int | None = None, ack: int | None = None,
                t: float | None = None, write: bool = True) -> Any:
        src, dst = (ROBOT_IP, BOX_IP) if from_robot else (BOX_IP, ROBOT_IP)
        sport, dport = (self.rport, self.bport) if from_robot else (self.bport, self.rport)
        seq = self.seq[from_robot] if seq is None else seq
        ack = self.seq[not from_robot] if ack is None else ack
        pkt = self.cap.frame(src, dst, TCP(sport=sport, dport=dport, flags=flags, seq=seq, ack=ack, window=65535), data)
        if write:
            self.cap.add(pkt, t)
        else:
            pkt.time = self.cap.t if t is None else t
        return pkt

    def send(self, from_robot: bool, data: bytes, t: float | None = None, write: bool = True) -> Any:
        pkt = self.segment(from_robot, "PA", data, t=t, write=write)
        self.seq[from_robot] += len(data)
        return pkt

    def robot(self, data: bytes, t: float | None = None) -> Any:
        return self.send(True, data, t)

    def box(self, data: bytes, t: float | None = None) -> Any:
        return self.send(False, data, t)

    def ack(self, from_robot: bool, t: float | None = None) -> Any:
        return self.segment(from_robot, "A", b"", t=t)

    def close(self, robot_first: bool = True) -> None:
        first = robot_first
        self.segment(first, "FA", b"")
        self.seq[first] += 1
        self.segment(not first, "FA", b"")
        self.seq[not first] += 1
        self.segment(first, "A", b"")

    def reset(self, from_robot: bool = True) -> Any:
        return self.segment(from_robot, "R", b"")


def exchange(conn: TcpConn, req: bytes, ans: bytes | None, gap: float = 0.0005) -> None:
    """The robot sends ``req``; the box answers ``ans`` (None: no answer) ``gap`` seconds later."""
    conn.robot(req)
    if ans is not None:
        conn.box(ans, t=conn.cap.t + gap)


def canonical(cap: Capture, poses: int = 20, port: int = 41000, rate_hz: float = 50.0,
              answers: Callable[[int, bytes], bytes | None] | None = None) -> tuple[TcpConn, TcpConn]:
    """A canonical S1 session written by hand: command connect, stream with ``poses`` poses at ``rate_hz``
    (CycleOn after the first pose, CycleOff before the last), stream close, command close."""
    period = 1.0 / rate_hz
    cmd = cap.tcp(port)
    stream = cap.tcp(port + 1)
    for i in range(poses):
        t = cap.t + (period if i else 0.001)
        stream.robot(POSE, t=t)
        ans = POSE_OK if answers is None else answers(i, POSE)
        if ans is not None:
            stream.box(ans, t=t + 0.0004)
        if i == 0:
            exchange(cmd, encode(request(Action.CYCLE_ON)), encode(answer(Action.CYCLE_ON)))
        if i == poses - 2:
            exchange(cmd, encode(request(Action.CYCLE_OFF)), encode(answer(Action.CYCLE_OFF)))
    stream.close()
    cmd.close()
    return cmd, stream

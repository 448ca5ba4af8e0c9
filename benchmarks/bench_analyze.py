"""Speed and memory of ``analyze`` on a generated capture.

Run on demand: ``python benchmarks/bench_analyze.py [--frames N] [--format pcap|pcapng]``.
The capture is written with ``struct`` (raw records, not scapy packets): sessions of
the canonical shape one after another, each a command connection (handshake, CycleOn,
CycleOff, close) and a stream connection (handshake, poses at 50 Hz each answered
0.4 ms later, a pure ACK every tenth pose, close), with 2 % unrelated TCP traffic mixed
in. Each analysis runs in a child process that reports its own peak RSS (VmHWM); the full size
and half of it are analysed, so the two RSS figures show whether memory grows with
the capture's size (``--one-session``: one stream carries nearly all of them, so the
figures show that a connection's state does not grow with its length either). Goal: at
least 200,000 frames/s, and the same RSS at both sizes.
"""

from __future__ import annotations

import argparse
import heapq
import json
import os
import struct
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from conformance.protocol import Action, answer, encode_tcp, pose_blocks, request  # noqa: E402

ROBOT, BOX, OTHER = bytes([10, 0, 0, 2]), bytes([10, 0, 0, 1]), bytes([10, 0, 0, 9])
ETH = bytes.fromhex("020000000001" "020000000002") + b"\x08\x00"
IP = struct.Struct("!BBHHHBBH4s4s")
TCP = struct.Struct("!HHIIBBHHH")
REC = struct.Struct("<IIII")
EPB = struct.Struct("<IIIIIII")
SYN, ACK, PSH, FIN = 0x02, 0x10, 0x08, 0x01
POSE = encode_tcp(request(Action.POSE, pose_blocks([(800.0, 10.0, 300.0, 180.0, 0.0, 90.0)])))
POSE_ANSWER = encode_tcp(answer(Action.POSE))
CYCLE = {a: (encode_tcp(request(a)), encode_tcp(answer(a))) for a in (Action.CYCLE_ON, Action.CYCLE_OFF)}


class Writer:
    def __init__(self, path: Path, fmt: str) -> None:
        self.f = open(path, "wb")  # noqa: SIM115 - closed in close()
        self.fmt = fmt
        self.buf: list[bytes] = []
        self.frames = 0
        if fmt == "pcap":
            self.f.write(struct.pack("<IHHiIII", 0xA1B2C3D4, 2, 4, 0, 0, 262144, 1))
        else:
            shb_body = struct.pack("<IHHq", 0x1A2B3C4D, 1, 0, -1)
            self.f.write(struct.pack("<II", 0x0A0D0D0A, 12 + len(shb_body)) + shb_body + struct.pack("<I", 12 + len(shb_body)))
            idb_body = struct.pack("<HHI", 1, 0, 0)
            self.f.write(struct.pack("<II", 1, 12 + len(idb_body)) + idb_body + struct.pack("<I", 12 + len(idb_body)))

    def packet(self, t: float, src: bytes, dst: bytes, sport: int, dport: int, seq: int, ack: int, flags: int,
               payload: bytes = b"") -> None:
        ip = IP.pack(0x45, 0, 40 + len(payload), 0, 0x4000, 64, 6, 0, src, dst)
        frame = ETH + ip + TCP.pack(sport, dport, seq & 0xFFFFFFFF, ack & 0xFFFFFFFF, 0x50, flags, 65535, 0, 0) + payload
        n = len(frame)
        if self.fmt == "pcap":
            sec = int(t)
            self.buf.append(REC.pack(sec, int((t - sec) * 1e6), n, n) + frame)
        else:
            us = int(t * 1e6)
            pad = -n % 4
            total = 32 + n + pad
            self.buf.append(EPB.pack(6, total, 0, us >> 32, us & 0xFFFFFFFF, n, n) + frame + b"\x00" * pad
                            + struct.pack("<I", total))
        self.frames += 1
        if len(self.buf) >= 8192:
            self.f.write(b"".join(self.buf))
            self.buf.clear()

    def close(self) -> None:
        self.f.write(b"".join(self.buf))
        self.f.close()


class Conn:
    """Sequence numbers of one connection robot:port -> box:9004; ``events`` collects its packets."""

    def __init__(self, events: list[tuple], port: int) -> None:
        self.events, self.port, self.r, self.b = events, port, 1000, 5000

    def open(self, t: float) -> None:
        p = self.port
        self.events += [(t, ROBOT, BOX, p, 9004, self.r, 0, SYN, b""),
                        (t + 0.0001, BOX, ROBOT, 9004, p, self.b, self.r + 1, SYN | ACK, b""),
                        (t + 0.0002, ROBOT, BOX, p, 9004, self.r + 1, self.b + 1, ACK, b"")]
        self.r, self.b = self.r + 1, self.b + 1

    def exchange(self, t: float, req: bytes, ans: bytes, pure_ack: bool = False) -> None:
        p = self.port
        self.events.append((t, ROBOT, BOX, p, 9004, self.r, self.b, PSH | ACK, req))
        self.r += len(req)
        self.events.append((t + 0.0004, BOX, ROBOT, 9004, p, self.b, self.r, PSH | ACK, ans))
        self.b += len(ans)
        if pure_ack:
            self.events.append((t + 0.0008, ROBOT, BOX, p, 9004, self.r, self.b, ACK, b""))

    def close(self, t: float) -> None:
        p = self.port
        self.events += [(t, ROBOT, BOX, p, 9004, self.r, self.b, FIN | ACK, b""),
                        (t + 0.0001, BOX, ROBOT, 9004, p, self.b, self.r + 1, FIN | ACK, b""),
                        (t + 0.0002, ROBOT, BOX, p, 9004, self.r + 1, self.b + 1, ACK, b"")]


def session(w: Writer, t: float, port: int, poses: int, other: int) -> float:
    """One canonical session starting at ``t``; returns when it ended. The stream's packets are
    made as they are written (a session may carry a million of them)."""
    events: list[tuple] = []
    cmd = Conn(events, port)
    cmd.open(t)
    first = t + 0.01
    last = first + 0.02 * (poses - 1)
    cmd.exchange(first + 0.09, *CYCLE[Action.CYCLE_ON])
    cmd.exchange(last - 0.09, *CYCLE[Action.CYCLE_OFF])
    cmd.close(last + 0.05)
    for i in range(other):  # unrelated traffic during the session
        events.append((t + 0.011 * i, OTHER, BOX, 50000, 443, 77 + 64 * i, 1, PSH | ACK, b"\x17\x03\x03" + bytes(61)))
    events.sort(key=lambda e: e[0])

    def stream_packets() -> Iterator[tuple]:
        batch: list[tuple] = []
        stream = Conn(batch, port + 1)
        stream.open(t + 0.005)
        yield from batch
        for i in range(poses):
            batch.clear()
            stream.exchange(first + 0.02 * i, POSE, POSE_ANSWER, pure_ack=i % 10 == 9)
            yield from batch
        batch.clear()
        stream.close(last + 0.02)
        yield from batch

    for e in heapq.merge(events, stream_packets(), key=lambda e: e[0]):
        w.packet(*e)
    return last + 0.06


def generate(path: Path, frames: int, fmt: str, poses: int = 500) -> int:
    w = Writer(path, fmt)
    t, port = 1_700_000_000.0, 20000
    per_session = 2 * poses + poses // 10 + 16
    while w.frames < frames:
        t = session(w, t, port, poses, per_session // 50) + 1.0
        port = 20000 + (port - 20000 + 2) % 40000
    w.close()
    return w.frames


def child(path: str, rounds: int) -> None:
    from conformance.analyze import AnalyzeConfig, analyze, build_cases

    best = None
    for _ in range(rounds):
        start = time.perf_counter()
        analysis = analyze(path, AnalyzeConfig())
        cases = build_cases(analysis)
        elapsed = time.perf_counter() - start
        best = elapsed if best is None else min(best, elapsed)
    verdicts: dict[str, int] = {}
    for c in cases:
        verdicts[c.verdict.value] = verdicts.get(c.verdict.value, 0) + 1
    print(json.dumps({"frames": analysis.frames, "seconds": best, "rss_kib": peak_rss_kib(),
                      "verdicts": verdicts, "sessions": analysis.ctx.stats.sessions}))


def peak_rss_kib() -> int:
    """This process's own peak RSS (VmHWM). Not getrusage's ru_maxrss: Linux carries that across
    exec, so a child would report its parent's peak from before the exec."""
    with open("/proc/self/status") as fh:
        for line in fh:
            if line.startswith("VmHWM:"):
                return int(line.split()[1])
    import resource

    return int(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss)


def measure(path: Path, rounds: int) -> dict:
    out = subprocess.run([sys.executable, __file__, "--child", str(path), "--rounds", str(rounds)],
                         capture_output=True, text=True, timeout=3600, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--frames", type=int, default=1_000_000)
    parser.add_argument("--format", choices=("pcap", "pcapng"), default="pcap")
    parser.add_argument("--rounds", type=int, default=1, help="analyses per size; the fastest counts")
    parser.add_argument("--one-session", action="store_true",
                        help="one session whose stream carries (nearly) all the frames, instead of sessions of 500 poses "
                             "(shows that a connection's state does not grow with its length)")
    parser.add_argument("--child", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        child(args.child, args.rounds)
        return
    with tempfile.TemporaryDirectory() as tmp:
        results = []
        for frames in (args.frames, args.frames // 2):
            path = Path(tmp) / f"bench-{frames}.{args.format}"
            t = time.perf_counter()
            written = generate(path, frames, args.format, poses=int(frames / 2.12) if args.one_session else 500)
            gen_s = time.perf_counter() - t
            r = measure(path, args.rounds)
            results.append(r)
            print(f"{written:>10,} frames ({path.stat().st_size / 1e6:.0f} MB {args.format}, written in {gen_s:.1f} s): "
                  f"analysed in {r['seconds']:.2f} s = {r['frames'] / r['seconds']:,.0f} frames/s; "
                  f"peak RSS {r['rss_kib'] / 1024:.1f} MiB; {r['sessions']} sessions; verdicts {r['verdicts']}")
            os.unlink(path)
        full, half = results
        print(f"peak RSS at full size {full['rss_kib'] / 1024:.1f} MiB, at half size {half['rss_kib'] / 1024:.1f} MiB "
              f"(difference {(full['rss_kib'] - half['rss_kib']) / 1024:+.1f} MiB)")
        load = os.getloadavg()[0]
        print(f"1-minute load average {load:.2f} on {os.cpu_count()} cores")


if __name__ == "__main__":
    main()

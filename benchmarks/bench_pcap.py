"""Cost of pcapng evidence per packet: the struct writer vs building packets with scapy.

Run on demand: ``python benchmarks/bench_pcap.py [--frames N]``. A stream case of N
pose frames, each sent and answered on its own (4 packets per frame: data, ACK,
answer, ACK), is written with :func:`write_transcript` and, live, through a
:class:`PcapRecorder` attached to the transcript (what a case pays). For comparison,
a sample of the same packets is built with scapy's ``Ether()/IP()/TCP()/Raw`` and
written with scapy's ``PcapNgWriter``.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from conformance.evidence.pcap import PcapRecorder, write_transcript  # noqa: E402
from conformance.harness.transcript import Endpoint, Kind, Transcript  # noqa: E402
from conformance.protocol import Action, answer, encode_tcp, pose_blocks, request  # noqa: E402


def stream_transcript(frames: int, recorder_path: Path | None = None) -> tuple[Transcript, float]:
    tr = Transcript(case_id="BENCH-001")
    if recorder_path is not None:
        PcapRecorder.attach(tr, recorder_path)
    req = encode_tcp(request(Action.POSE, pose_blocks([(1000.0, -250.5, 300.25, 180.0, -0.5, 90.0)])))
    ans = encode_tcp(answer(Action.POSE))
    start = time.perf_counter()
    c = tr.open("tcp", Endpoint("127.0.0.1", 40000), Endpoint("127.0.0.1", 9004), "stream")
    tr.add(c.conn, Kind.CONNECT)
    for i in range(frames):
        tr.add(c.conn, Kind.SEND, req, f"pose {i}")
        tr.add(c.conn, Kind.RECV, ans)
    tr.add(c.conn, Kind.CLOSE)
    tr.close()
    return tr, time.perf_counter() - start


def scapy_sample(n: int, path: Path) -> float:
    from scapy.layers.inet import IP, TCP
    from scapy.layers.l2 import Ether
    from scapy.packet import Raw
    from scapy.utils import PcapNgWriter

    payload = encode_tcp(request(Action.POSE, pose_blocks([(1.0, 2.0, 3.0, 4.0, 5.0, 6.0)])))
    start = time.perf_counter()
    with PcapNgWriter(str(path)) as w:
        for i in range(n):
            p = (
                Ether(src="00:00:00:00:00:00", dst="00:00:00:00:00:00")
                / IP(src="127.0.0.1", dst="127.0.0.1", flags="DF")
                / TCP(sport=40000, dport=9004, flags="PA", seq=1 + 39 * i, ack=1, window=65535)
                / Raw(payload)
            )
            p.time = 1_700_000_000 + i / 1000
            p.comments = [b"BENCH-001: pose"]
            w.write(p)
            w.flush()
    return time.perf_counter() - start


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--frames", type=int, default=10_000)
    ap.add_argument("--scapy-sample", type=int, default=2_000)
    args = ap.parse_args()
    packets = 4 * args.frames + 5  # + handshake and FIN/ACK
    with tempfile.TemporaryDirectory() as d:
        tmp = Path(d)
        tr, bare = stream_transcript(args.frames)
        start = time.perf_counter()
        write_transcript(tr, tmp / "after.pcapng")
        after = time.perf_counter() - start
        _, live = stream_transcript(args.frames, tmp / "live.pcapng")
        size = (tmp / "live.pcapng").stat().st_size
        sc = scapy_sample(args.scapy_sample, tmp / "scapy.pcapng")
    print(f"{args.frames} pose frames sent and answered: {packets} packets, {size / 1e6:.1f} MB pcapng")
    print(f"  write_transcript (after the fact): {after:.3f} s = {after / packets * 1e6:.1f} us/packet")
    print(f"  live PcapRecorder, whole case:     {live:.3f} s (transcript alone {bare:.3f} s)")
    print(
        f"    -> recording adds {(live - bare) / packets * 1e6:.1f} us/packet, {(live - bare) / args.frames * 1e6:.1f} us/frame"
    )
    print(
        f"  scapy Ether/IP/TCP/Raw + PcapNgWriter: {sc / args.scapy_sample * 1e6:.1f} us/packet "
        f"(would be {sc / args.scapy_sample * packets:.1f} s for this case)"
    )


if __name__ == "__main__":
    main()

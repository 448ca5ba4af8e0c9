"""Memory of ``analyze`` (and so of ``monitor``, the same engine) over days of one robot address.

Run on demand: ``python benchmarks/bench_long_capture.py [--frames 10000000] [--keep PATH] [--by-address]``.
The capture (in a temporary directory, or ``--keep PATH``: never commit it) is written
with ``struct``: ONE robot address (several robots behind one NAT address) whose traffic
never pauses: a command connection that stays open for the whole capture (a ping every
10 minutes: the "one-week connection"), and three robots taking turns with canonical
sessions of 500 poses at 50 Hz whose connections overlap, so at no moment is every
connection of the address closed. A session keyed by address alone would never end and
hold every connection's outcome; sessions split by connection lifetimes and time
(conformance/analyze/sessions.py) keep it flat.

The analysis runs in a child process that samples its own RSS (VmRSS) at every 5 % of the
capture read; the curve is printed as (frames read, RSS MiB), with the baseline of the
first sample, the peak (VmHWM) and the growth from 25 % to 100 %.
"""

from __future__ import annotations

import argparse
import heapq
import json
import os
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks.bench_analyze import CYCLE, POSE, POSE_ANSWER, Conn, Writer  # noqa: E402
from conformance.protocol import Action, answer, encode_tcp, request  # noqa: E402

PING = (encode_tcp(request(Action.NONE)), encode_tcp(answer(Action.NONE)))
POSES = 500
ROBOTS = 3  # behind one address, taking turns with overlapping sessions


def _session(t: float, port: int) -> Iterator[tuple]:
    """One canonical session from ``t``: command + stream connection of 500 poses, in time order."""
    events: list[tuple] = []
    cmd = Conn(events, port)
    cmd.open(t)
    first = t + 0.01
    last = first + 0.02 * (POSES - 1)
    cmd.exchange(first + 0.09, *CYCLE[Action.CYCLE_ON])
    cmd.exchange(last - 0.09, *CYCLE[Action.CYCLE_OFF])
    cmd.close(last + 0.05)
    stream: list[tuple] = []
    s = Conn(stream, port + 1)
    s.open(t + 0.005)
    for i in range(POSES):
        s.exchange(first + 0.02 * i, POSE, POSE_ANSWER, pure_ack=i % 10 == 9)
    s.close(last + 0.02)
    yield from heapq.merge(sorted(events, key=lambda e: e[0]), stream, key=lambda e: e[0])


def _robot(n: int, t0: float, until: int, counter: list[int]) -> Iterator[tuple]:
    """Robot ``n``'s sessions one after another (its own ports), staggered against the others."""
    t = t0 + n * 3.5
    port = 20000 + n * 10000
    while counter[0] < until:
        yield from _session(t, port)
        t += 0.02 * POSES + 0.6  # the next session 0.5 s after this one ends
        port = 20000 + n * 10000 + (port - 20000 - n * 10000 + 2) % 9998


def _long_connection(t0: float, counter: list[int], until: int) -> Iterator[tuple]:
    events: list[tuple] = []
    conn = Conn(events, 19999)
    conn.open(t0)
    t = t0
    while counter[0] < until:
        t += 600.0
        conn.exchange(t, *PING)
        yield from events
        events.clear()
    conn.close(t + 1)
    yield from events


def generate(path: Path, frames: int) -> int:
    w = Writer(path, "pcap")
    counter = [0]
    t0 = 1_700_000_000.0
    streams = [_robot(n, t0, frames, counter) for n in range(ROBOTS)]
    merged = heapq.merge(_long_connection(t0 - 1.0, counter, frames), *streams, key=lambda e: e[0])
    for e in merged:
        w.packet(*e)
        counter[0] = w.frames
        if w.frames >= frames + 64 and e[7] & 0x01 and e[3] == 19999:
            break  # the long connection's FIN: the end
    w.close()
    return w.frames


def child(path: str, samples: int, by_address: bool = False) -> None:
    from conformance.analyze import AnalyzeConfig, analyze, build_cases

    if by_address:  # the baseline: sessions by address alone (never split), as before issue 26
        from conformance.analyze import sessions

        sessions.SPLIT_CONNECTIONS, sessions.SPLIT_AFTER_S = 1 << 62, float("inf")

    size = os.path.getsize(path)
    curve: list[tuple[float, float]] = []
    step = max(1, size // samples)
    mark = [0]

    def progress(position: int, total: int) -> None:
        if position >= mark[0]:
            mark[0] = position + step
            curve.append((position / size, _status("VmRSS:") / 1024))

    start = time.perf_counter()
    analysis = analyze(path, AnalyzeConfig(rate_tolerance=0.5, jitter_tolerance=3.0), progress)
    cases = build_cases(analysis)
    elapsed = time.perf_counter() - start
    verdicts: dict[str, int] = {}
    for c in cases:
        verdicts[c.verdict.value] = verdicts.get(c.verdict.value, 0) + 1
    print(json.dumps({"frames": analysis.frames, "seconds": elapsed, "hwm_mib": _status("VmHWM:") / 1024,
                      "curve": curve, "sessions": analysis.ctx.stats.sessions, "verdicts": verdicts}))


def _status(key: str) -> int:
    with open("/proc/self/status") as fh:
        for line in fh:
            if line.startswith(key):
                return int(line.split()[1])
    return 0


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--frames", type=int, default=10_000_000)
    parser.add_argument("--keep", type=Path, help="write the capture here and keep it (never commit it)")
    parser.add_argument("--samples", type=int, default=20)
    parser.add_argument("--by-address", action="store_true",
                        help="the baseline: sessions keyed by address alone, never split (as before issue 26)")
    parser.add_argument("--child", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        child(args.child, args.samples, args.by_address)
        return
    with tempfile.TemporaryDirectory() as tmp:
        path = args.keep or Path(tmp) / "long.pcap"
        t = time.perf_counter()
        again = args.keep is not None and args.keep.exists()  # analyse the kept capture again
        written = -1 if again else generate(path, args.frames)
        print(f"{written:,} frames (-1: the kept capture) from one robot address ({path.stat().st_size / 1e9:.2f} GB pcap) written in "
              f"{time.perf_counter() - t:.0f} s", flush=True)
        out = subprocess.run([sys.executable, __file__, "--child", str(path), "--samples", str(args.samples),
                              *(["--by-address"] if args.by_address else [])],
                             capture_output=True, text=True, timeout=6 * 3600)
        if out.returncode:
            print(out.stderr[-2000:])
            sys.exit(1)
        r = json.loads(out.stdout.strip().splitlines()[-1])
        print(f"analysed in {r['seconds']:.0f} s ({r['frames'] / r['seconds']:,.0f} frames/s); {r['sessions']:,} "
              f"sessions; verdicts {r['verdicts']}")
        print("RSS curve (share of the capture read -> frames read, RSS MiB):")
        for share, mib in r["curve"]:
            print(f"  {share * 100:5.1f} %  {int(share * r['frames']):>11,}  {mib:8.1f}")
        curve = r["curve"]
        quarter = next((m for s, m in curve if s >= 0.25), curve[0][1])
        print(f"baseline (first sample) {curve[0][1]:.1f} MiB; at 25 % {quarter:.1f} MiB; at the end {curve[-1][1]:.1f} "
              f"MiB (growth from 25 % to the end {curve[-1][1] - quarter:+.1f} MiB); peak {r['hwm_mib']:.1f} MiB")
        print(f"1-minute load average {os.getloadavg()[0]:.2f} on {os.cpu_count()} cores")


if __name__ == "__main__":
    main()

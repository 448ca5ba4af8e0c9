"""Abuse on the reference AI Box while one well-behaved robot runs the canonical session.

Run on demand (loopback only, bounded in time)::

    python benchmarks/bench_box_abuse.py                      # 760 abusive connections, 10 s session
    python benchmarks/bench_box_abuse.py --partial 500 --oversize 500 --duration 20

The box runs in another process (``python -m conformance serve --port 0 --no-udp``).
A child process opens the abusive connections and holds them for the whole run:

* ``--partial``: a pose frame's first 20 bytes, then nothing (R5: partial frames left hanging);
* ``--hanging``: a legal header announcing 255 pose blocks and 6000 of its 6377 bytes
  (the box must hold the most a frame can need, 6389 bytes, per connection);
* ``--oversize``: a header announcing 255 × 65535 bytes, then 4 KiB of junk;
* ``--drip``: one garbage byte every 100 ms (slowloris);
* ``--nonreaders``: poses as fast as the box takes them, answers never read
  (the box must stop reading them rather than buffer their answers).

Once the box has worked through what the set-up left in its sockets (its CPU use
drops under 10 %, at most 15 s; printed),
this process runs :class:`~conformance.endpoints.robot.RobotSession` (S1, or E4
with ``--extension``) and prints the good robot's verdict, its pose-answer latency
p50/p99/max and send jitter, and the box's peak RSS (VmHWM) and RSS from
/proc/PID/status, before and after.
"""

from __future__ import annotations

import argparse
import contextlib
import multiprocessing
import os
import socket
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from bench_box_load import BoxProcess, pose_frames  # noqa: E402

from conformance.endpoints.robot import RobotSession, run_robot  # noqa: E402
from conformance.endpoints.serve import raise_fd_limit  # noqa: E402
from conformance.protocol import DEFAULT_PROFILE, Header, encode_raw  # noqa: E402


def _abuser(host: str, port: int, counts: dict[str, int], ready, stop) -> None:  # type: ignore[no-untyped-def]
    raise_fd_limit(sum(counts.values()) + 256)
    pose = pose_frames(1)[0]
    hanging = encode_raw(Header(action=0x23, block_type=1, block_count=255, block_length=25))[:12] + bytes(6000)
    oversize = encode_raw(Header(action=0x23, block_type=1, block_count=255, block_length=0xFFFF))[:12] + b"\xab" * 4096
    socks: dict[str, list[socket.socket]] = {k: [] for k in counts}
    failed = 0
    for kind, count in counts.items():
        for _ in range(count):
            try:
                s = socket.create_connection((host, port), timeout=5)
            except OSError:
                failed += 1
                continue
            socks[kind].append(s)
            if kind == "partial":
                s.sendall(pose[:20])
            elif kind == "hanging":
                s.sendall(hanging)
            elif kind == "oversize":
                s.sendall(oversize)
            elif kind == "nonreaders":
                s.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
            s.setblocking(False)
    # the non-readers push poses until the box stops taking them (back-pressure)
    flood = pose * 2000
    pushed = 0
    deadline = time.monotonic() + 10
    for s in socks["nonreaders"]:
        while time.monotonic() < deadline:
            try:
                pushed += s.send(flood)
            except BlockingIOError:
                break
            except OSError:
                break
    ready.send({"opened": {k: len(v) for k, v in socks.items()}, "failed": failed, "pushed_bytes": pushed})
    # drip until told to stop (bounded by the parent's run time)
    while not stop.poll(0.1):
        for s in socks["drip"]:
            with contextlib.suppress(OSError):
                s.send(b"\x13")
    alive = 0
    for group in socks.values():
        for s in group:
            try:
                s.setblocking(False)
                alive += s.recv(1) != b""
            except BlockingIOError:
                alive += 1  # still open, nothing to read
            except OSError:
                pass
            s.close()
    stop.send({"still_open": alive})


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--partial", type=int, default=200, help="connections holding a partial frame (default 200)")
    parser.add_argument("--hanging", type=int, default=200,
                        help="connections holding 6000 bytes of a legal 6389-byte frame (default 200)")
    parser.add_argument("--oversize", type=int, default=200,
                        help="connections that announced 255 x 65535 bytes (default 200)")
    parser.add_argument("--drip", type=int, default=100, help="connections dripping a garbage byte every 100 ms "
                        "(default 100)")
    parser.add_argument("--nonreaders", type=int, default=10, help="connections flooding poses and never reading "
                        "(default 10)")
    parser.add_argument("--duration", type=float, default=10.0, help="the good robot's trajectory, s (default 10)")
    parser.add_argument("--extension", action="store_true", help="the good robot plays E4 instead of S1")
    parser.add_argument("--box-loop", choices=("asyncio", "uvloop"), default="asyncio", help="the box's event loop")
    args = parser.parse_args()
    if not 0 < args.duration <= 120:
        parser.error("--duration must be in (0, 120]")
    counts = {"partial": args.partial, "hanging": args.hanging, "oversize": args.oversize, "drip": args.drip,
              "nonreaders": args.nonreaders}
    if min(counts.values()) < 0:
        parser.error("counts must be >= 0")
    total = sum(counts.values())
    raise_fd_limit(total + 256)
    box_args = ["--no-udp", "--max-connections", str(max(2000, total + 100)), "--loop", args.box_loop]
    with BoxProcess(*box_args) as box:
        print(f"box: pid {box.pid}, {box.command}")
        before = box.memory()
        ctx = multiprocessing.get_context("fork")
        ready_parent, ready_child = ctx.Pipe()
        stop_parent, stop_child = ctx.Pipe()
        worker = ctx.Process(target=_abuser, args=(box.host, box.port, counts, ready_child, stop_child))
        worker.start()
        t0 = time.monotonic()
        if not ready_parent.poll(120):
            worker.kill()
            raise RuntimeError("the abusive connections were not set up in 120 s")
        setup = ready_parent.recv()
        print(f"abuse: {setup['opened']} opened in {time.monotonic() - t0:.2f} s "
              f"(failed {setup['failed']}); non-readers pushed {setup['pushed_bytes'] / 1e6:.1f} MB before the box "
              "stopped reading them")
        # let the box finish the backlog the set-up left in its sockets (accepts, floods) so that
        # the robot measures the steady state under abuse: until the box uses < 10 % CPU (max 15 s)
        settle_start = time.monotonic()
        while time.monotonic() - settle_start < 15:
            cpu = box.cpu_seconds()
            time.sleep(0.2)
            if box.cpu_seconds() - cpu < 0.02:
                break
        print(f"  the box settled {time.monotonic() - settle_start:.1f} s after the set-up")
        during = box.memory()
        session = RobotSession((box.host, box.port), DEFAULT_PROFILE, duration=args.duration,
                               extension=args.extension)
        result = run_robot(session)
        after = box.memory()
        stop_parent.send("stop")
        still = stop_parent.recv() if stop_parent.poll(30) else {"still_open": "?"}
        worker.join(10)
        if worker.is_alive():
            worker.kill()
        mean, worst = result.jitter_ms
        print(f"good robot ({'E4' if args.extension else 'S1'}, {args.duration:g} s at "
              f"{DEFAULT_PROFILE.pose_rate_hz:g} Hz): exit {result.exit_code}, {result.reason}")
        print(f"  poses sent {result.poses_sent}, answered {result.poses_answered}")
        print(f"  pose answer latency ms: p50 {result.latency(50):.2f}  p99 {result.latency(99):.2f}  "
              f"max {result.latency(100):.2f}")
        print("  command answers ms: " + "  ".join(f"{k} {v:.2f}" for k, v in result.command_latencies_ms.items()))
        print(f"  send-interval jitter ms: mean {mean:.2f}  max {worst:.2f}")
        mb = 1024.0
        print(f"  box RSS MB: before abuse {before.get('VmRSS', 0) / mb:.1f}, with abuse {during.get('VmRSS', 0) / mb:.1f}, "
              f"after the session {after.get('VmRSS', 0) / mb:.1f}; peak (VmHWM) {after.get('VmHWM', 0) / mb:.1f}")
        print(f"  abusive connections still open at the end: {still['still_open']} of {total}")
        summary = box.stop()
        print(f"  box: {summary.splitlines()[-1] if summary else '(no summary)'}")
    print(f"  machine load average (1 min): {os.getloadavg()[0]:.2f} ({os.cpu_count()} cores; other processes skew "
          "the figures)")
    return result.exit_code


if __name__ == "__main__":
    sys.exit(main())

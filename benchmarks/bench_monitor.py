"""What the in-line monitor costs: added latency, forwarding rate, memory and files over a soak, ring disk use.

Run on demand (loopback only, bounded in time)::

    python benchmarks/bench_monitor.py                 # all four, a 5-minute soak
    python benchmarks/bench_monitor.py --soak-minutes 30
    python benchmarks/bench_monitor.py --only latency throughput

The box and the monitor each run in their own process (``python -m conformance serve
--port 0 --no-udp`` and ``python -m conformance monitor ... --quiet``); the load is
this process (asyncio).

* **latency**: 10 robots × 50 Hz, each on one connection sending a pose every 20 ms
  and timing its answer; alternating 10-second phases straight to the box and through
  the monitor (same box, same run), two of each. Printed: p50/p99 of each and the
  difference (what the monitor adds).
* **throughput**: one connection, poses pipelined in writes of 256 frames with 4096 in
  flight, through the monitor to a box stand-in that answers every pose with its
  14-byte answer by the batch (so the box is not what is measured). Printed: frames/s
  forwarded each way, with the pcapng ring on and with ``--no-pcap``.
* **soak**: 10 robot simulators (``RobotSession``, canonical sessions of 10 s, one after
  another; each from its own loopback address 127.0.0.10-19, as robots at a plant) at 50 Hz through the monitor with ``--ring 5 --ring-mb 5``; the monitor's
  RSS (VmRSS) and open files (/proc/PID/fd) sampled every ``--sample-s``. Printed: the
  samples, and the RSS change from the first sample after minute 1 (or the first) to the last.
* **ring**: the pcapng ring's files and bytes on disk at the end of the soak, and the
  bytes per hour the soak's traffic writes.
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import contextvars
import json
import os
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from conformance.model.percentiles import percentile  # noqa: E402
from conformance.protocol import Action, encode_tcp, pose_blocks, request  # noqa: E402

POSE = encode_tcp(request(Action.POSE, pose_blocks([(1.0, 2.0, 3.0, 4.0, 5.0, 6.0)])))
ANSWER = bytes.fromhex("fefe000110230000000000000000")


def _start(args: list[str]) -> tuple[subprocess.Popen[str], str]:
    proc = subprocess.Popen([sys.executable, "-m", "conformance", *args], stdout=subprocess.PIPE,
                            stderr=subprocess.DEVNULL, text=True, cwd=ROOT)
    assert proc.stdout is not None
    return proc, proc.stdout.readline().split()[2]


def _stop(proc: subprocess.Popen[str]) -> None:
    proc.send_signal(signal.SIGTERM)
    try:
        proc.wait(60)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.wait()


def _monitor(upstream: str, tmp: Path, *extra: str) -> tuple[subprocess.Popen[str], str]:
    return _start(["monitor", "--listen", "127.0.0.1:0", "--upstream", upstream, "--quiet", "--checkpoint", "0",
                   "--report-dir", str(tmp / "report"), "--pcap-dir", str(tmp / "pcaps"), *extra])


def _addr(text: str) -> tuple[str, int]:
    host, _, port = text.rpartition(":")
    return host, int(port)


# -- latency -----------------------------------------------------------------------------------------
async def _robot(target: tuple[str, int], seconds: float, offset: float, out: list[float]) -> None:
    reader, writer = await asyncio.open_connection(*target)
    await asyncio.sleep(offset)
    loop = asyncio.get_running_loop()
    start = loop.time()
    n = 0
    while loop.time() - start < seconds:
        t = time.perf_counter()
        writer.write(POSE)
        await reader.readexactly(len(ANSWER))
        out.append((time.perf_counter() - t) * 1000.0)
        n += 1
        await asyncio.sleep(max(0.0, start + n * 0.02 - loop.time()))
    writer.close()


async def _phase(target: tuple[str, int], seconds: float, robots: int = 10) -> list[float]:
    out: list[float] = []
    await asyncio.gather(*(_robot(target, seconds, i * 0.002, out) for i in range(robots)))
    return out


def bench_latency(tmp: Path, phase_s: float) -> None:
    box, box_addr = _start(["serve", "--port", "0", "--no-udp"])
    mon, mon_addr = _monitor(box_addr, tmp / "latency")
    try:
        direct: list[float] = []
        through: list[float] = []
        for _ in range(2):
            direct += asyncio.run(_phase(_addr(box_addr), phase_s))
            through += asyncio.run(_phase(_addr(mon_addr), phase_s))
    finally:
        _stop(mon)
        _stop(box)
    d50, d99 = percentile(direct, 50), percentile(direct, 99)
    t50, t99 = percentile(through, 50), percentile(through, 99)
    print(f"latency, 10 robots x 50 Hz, {len(direct):,} + {len(through):,} poses in alternating {phase_s:g} s phases")
    print(f"  straight to the box: p50 {d50:.3f} ms  p99 {d99:.3f} ms")
    print(f"  through the monitor: p50 {t50:.3f} ms  p99 {t99:.3f} ms")
    print(f"  added by the monitor: p50 {t50 - d50:+.3f} ms  p99 {t99 - d99:+.3f} ms  (goal: p99 <= 0.5 ms)")


# -- throughput -----------------------------------------------------------------------------------------
def _answer_box() -> None:
    """A box stand-in for the throughput figure: every whole pose answered by the batch."""
    async def serve(reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        rest = 0
        while data := await reader.read(1 << 16):
            rest += len(data)
            n, rest = divmod(rest, len(POSE))
            writer.write(ANSWER * n)
            await writer.drain()
        writer.close()

    async def main() -> None:
        server = await asyncio.start_server(serve, "127.0.0.1", 0)
        print(f"listening tcp 127.0.0.1:{server.sockets[0].getsockname()[1]}", flush=True)
        await server.serve_forever()

    with contextlib.suppress(KeyboardInterrupt):
        asyncio.run(main())


async def _pipelined(target: tuple[str, int], seconds: float, chunk: int = 256, window: int = 4096) -> int:
    reader, writer = await asyncio.open_connection(*target)
    batch = POSE * chunk
    sent = answered = 0
    end = time.perf_counter() + seconds
    pending = 0
    while time.perf_counter() < end:
        while sent - answered < window:
            writer.write(batch)
            sent += chunk
        await writer.drain()
        data = await reader.read(1 << 20)
        if not data:
            break
        pending += len(data)
        got, pending = divmod(pending, len(ANSWER))
        answered += got
    writer.close()
    return answered


def bench_throughput(tmp: Path, seconds: float) -> None:
    box = subprocess.Popen([sys.executable, __file__, "--answer-box"], stdout=subprocess.PIPE, text=True)
    assert box.stdout is not None
    box_addr = box.stdout.readline().split()[2]
    try:
        for label, extra in (("ring on", ()), ("--no-pcap", ("--no-pcap",))):
            mon, mon_addr = _monitor(box_addr, tmp / f"throughput-{len(extra)}", *extra)
            try:
                t = time.perf_counter()
                answered = asyncio.run(_pipelined(_addr(mon_addr), seconds))
                elapsed = time.perf_counter() - t
            finally:
                _stop(mon)
            print(f"throughput, one pipelined connection through the monitor ({label}): {answered / elapsed:,.0f} "
                  f"poses/s and as many answers/s forwarded ({2 * answered / elapsed:,.0f} frames/s both ways; "
                  f"goal >= 100,000)")
        direct = asyncio.run(_pipelined(_addr(box_addr), seconds))
        print(f"  the same straight to the box stand-in: {direct / seconds:,.0f} poses/s")
    finally:
        box.terminate()
        box.wait()


# -- soak and ring -------------------------------------------------------------------------------------------
def _proc_figures(pid: int) -> tuple[float, int]:
    rss = 0.0
    with open(f"/proc/{pid}/status") as f:
        for line in f:
            if line.startswith("VmRSS:"):
                rss = int(line.split()[1]) / 1024.0
    return rss, len(os.listdir(f"/proc/{pid}/fd"))


_SOURCE: contextvars.ContextVar[str] = contextvars.ContextVar("source", default="127.0.0.1")


def _from_source(loop: asyncio.AbstractEventLoop) -> None:
    """The robots' connections leave from their own loopback address (127.0.0.N): as at a plant, each robot
    is its own address, so each robot's sessions end (one address is one robot to the engine)."""
    create = loop.create_connection

    async def create_connection(*args, **kw):  # type: ignore[no-untyped-def]
        kw.setdefault("local_addr", (_SOURCE.get(), 0))
        return await create(*args, **kw)

    loop.create_connection = create_connection  # type: ignore[method-assign]


async def _sessions(target: tuple[str, int], until: float, counts: list[int], source: str) -> None:
    from conformance.endpoints.robot import RobotSession

    _SOURCE.set(source)
    while time.monotonic() < until:
        result = await RobotSession(target, duration=10.0).run()
        counts[0 if result.ok else 1] += 1
        if not result.ok:
            await asyncio.sleep(0.5)


async def _soak_load(target: tuple[str, int], minutes: float, pid: int, sample_s: float) -> list[tuple[float, float, int]]:
    until = time.monotonic() + minutes * 60.0
    counts = [0, 0]
    _from_source(asyncio.get_running_loop())
    tasks = [asyncio.ensure_future(_sessions(target, until, counts, f"127.0.0.{10 + i}")) for i in range(10)]
    samples = []
    start = time.monotonic()
    while time.monotonic() < until:
        rss, fds = _proc_figures(pid)
        samples.append((time.monotonic() - start, rss, fds))
        print(f"  {samples[-1][0] / 60:5.1f} min  RSS {rss:7.1f} MB  open files {fds}  sessions {counts[0]} ok, "
              f"{counts[1]} not", flush=True)
        await asyncio.sleep(sample_s)
    await asyncio.gather(*tasks)
    rss, fds = _proc_figures(pid)
    samples.append((time.monotonic() - start, rss, fds))
    print(f"  {samples[-1][0] / 60:5.1f} min  RSS {rss:7.1f} MB  open files {fds}  sessions {counts[0]} ok, "
          f"{counts[1]} not (end)")
    return samples


def bench_soak(tmp: Path, minutes: float, sample_s: float) -> None:
    box, box_addr = _start(["serve", "--port", "0", "--no-udp"])
    mon, mon_addr = _monitor(box_addr, tmp / "soak", "--ring", "5", "--ring-mb", "5")
    print(f"soak, 10 robot simulators x 50 Hz through the monitor for {minutes:g} min, ring 5 x 5 MB")
    try:
        samples = asyncio.run(_soak_load(_addr(mon_addr), minutes, mon.pid, sample_s))
    finally:
        _stop(mon)
        _stop(box)
    steady = [s for s in samples if s[0] >= 60.0] or samples
    print(f"  RSS from {steady[0][0] / 60:.1f} min to the end: {steady[0][1]:.1f} -> {steady[-1][1]:.1f} MB "
          f"({steady[-1][1] - steady[0][1]:+.1f} MB; max {max(s[1] for s in steady):.1f}); open files "
          f"{min(s[2] for s in samples)}-{max(s[2] for s in samples)}")
    pcaps = sorted((tmp / "soak" / "pcaps").glob("*.pcapng"))
    size = sum(p.stat().st_size for p in pcaps)
    info = json.loads((tmp / "soak" / "report" / "monitor.json").read_text())
    print(f"ring: {len(pcaps)} file(s), {size / 1e6:.1f} MB on disk at the end (bound about 5 x 5 MB); "
          f"{info['packets']:,} packets, {info['sessions']:,} sessions in {info['seconds']:.0f} s: this traffic "
          f"writes about {_per_hour(tmp / 'soak', info):,.0f} MB per hour")


def _per_hour(directory: Path, info: dict) -> float:  # type: ignore[type-arg]
    """MB per hour written: every file but the newest is full (5 MB), plus the newest's size."""
    pcaps = sorted((directory / "pcaps").glob("*.pcapng"))
    numbers = [int(p.stem.split("_")[1]) for p in pcaps]
    total = (max(numbers) - 1) * 5e6 + pcaps[-1].stat().st_size if pcaps else 0
    return total / 1e6 / max(info["seconds"], 1) * 3600


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--only", nargs="*", choices=("latency", "throughput", "soak"), default=None)
    p.add_argument("--phase-s", type=float, default=10.0, help="seconds per latency phase (default 10)")
    p.add_argument("--throughput-s", type=float, default=8.0, help="seconds of pipelined load (default 8)")
    p.add_argument("--soak-minutes", type=float, default=5.0, help="soak length (default 5)")
    p.add_argument("--sample-s", type=float, default=30.0, help="seconds between soak samples (default 30)")
    p.add_argument("--answer-box", action="store_true", help=argparse.SUPPRESS)
    args = p.parse_args()
    if args.answer_box:
        _answer_box()
        return
    only = set(args.only or ("latency", "throughput", "soak"))
    with tempfile.TemporaryDirectory(prefix="bench-monitor-") as tmp:
        if "latency" in only:
            bench_latency(Path(tmp), args.phase_s)
        if "throughput" in only:
            bench_throughput(Path(tmp), args.throughput_s)
        if "soak" in only:
            bench_soak(Path(tmp), args.soak_minutes, args.sample_s)


if __name__ == "__main__":
    main()

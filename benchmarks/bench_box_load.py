"""Load on the reference AI Box: N robots streaming poses at R Hz, or one pipelined connection.

Run on demand (loopback only, bounded in time)::

    python benchmarks/bench_box_load.py --robots 1000 --rate 50 --duration 10
    python benchmarks/bench_box_load.py --pipelined --duration 5

The box runs in another process (``python -m conformance serve --port 0 --no-udp``).
The load generator is this process (or ``--procs`` forked worker processes), one
asyncio loop each with raw ``asyncio.Protocol`` connections. Every robot sends one
pose frame per period on a fixed clock (robots spread evenly over the period,
1 ms resolution; a late tick catches up, it never drifts), timestamps each request
and matches answers in order. Printed: frames/s answered, lost and wrong answers,
answer latency p50/p99/p99.9/max, how late the generator's sends were (send lag),
the box's CPU use and RSS (VmHWM peak / VmRSS from /proc/PID/status).

``--pipelined``: one connection sends pose frames as fast as the box answers them,
keeping ``--window`` frames in flight, in writes of ``--chunk`` frames; prints the
answered frames/s.
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import multiprocessing
import os
import re
import signal
import socket
import subprocess
import sys
import time
from array import array
from collections import deque
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from conformance.endpoints.loop import new_event_loop  # noqa: E402
from conformance.endpoints.serve import raise_fd_limit  # noqa: E402
from conformance.harness.trajectory import PrimerTrajectory  # noqa: E402
from conformance.model.percentiles import percentile  # noqa: E402
from conformance.protocol import Action, answer, encode, pose_blocks, request  # noqa: E402

ANSWER = encode(answer(Action.POSE))  # 14 bytes: the only right answer to a valid pose
ANSWER_LEN = len(ANSWER)
perf = time.perf_counter


# -- the box in a child process ---------------------------------------------------------------------


class BoxProcess:
    """``python -m conformance serve --port 0 ...`` in a child process (loopback only)."""

    def __init__(self, *extra: str, host: str = "127.0.0.1") -> None:
        if host not in ("127.0.0.1", "::1"):
            raise ValueError("the benchmarks only talk to loopback")
        cmd = [sys.executable, "-m", "conformance", "serve", "--host", host, "--port", "0", *extra]
        env = dict(os.environ, PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""))
        self.command = " ".join(cmd[1:])
        self.proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env, cwd=ROOT)
        assert self.proc.stdout is not None
        line = self.proc.stdout.readline()
        match = re.match(r"listening tcp \[?([^\]\s]+?)\]?:(\d+)", line)
        if not match:
            err = self.proc.stderr.read() if self.proc.stderr else ""
            self.proc.kill()
            raise RuntimeError(f"the box did not start: {line!r} {err}")
        self.host = match.group(1)
        self.port = int(match.group(2))
        self.pid = self.proc.pid

    def memory(self) -> dict[str, int]:
        """VmRSS and VmHWM (peak RSS) of the box in kB, from /proc/PID/status."""
        out: dict[str, int] = {}
        with contextlib.suppress(OSError), open(f"/proc/{self.pid}/status") as fh:
            for line in fh:
                if line.startswith(("VmRSS:", "VmHWM:")):
                    key, value = line.split(":", 1)
                    out[key] = int(value.split()[0])
        return out

    def cpu_seconds(self) -> float:
        """User + system CPU seconds the box has used."""
        with contextlib.suppress(OSError), open(f"/proc/{self.pid}/stat") as fh:
            fields = fh.read().rsplit(")", 1)[1].split()
            return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")
        return 0.0

    def stop(self) -> str:
        """SIGTERM, wait, and return the box's stderr (its one-line summary)."""
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGTERM)
            try:
                self.proc.wait(15)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait(5)
        return self.proc.stderr.read().strip() if self.proc.stderr else ""

    def __enter__(self) -> BoxProcess:
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()


def pose_frames(count: int = 50) -> list[bytes]:
    """``count`` valid pose frames along the primer trajectory."""
    trajectory = PrimerTrajectory(duration=1.0)
    return [
        encode(request(Action.POSE, pose_blocks([trajectory.pose_at(i / count)])))
        for i in range(count)
    ]


# -- the robots ---------------------------------------------------------------------------------------


#: one receive buffer shared by every connection of a generator process (asyncio's plain
#: Protocol would allocate 256 KiB per read, which costs ~10 us each: see box.py)
_BUFFER = memoryview(bytearray(1 << 16))


class _SharedBufferClient(asyncio.BufferedProtocol):
    """Reads into the shared buffer and hands each read to ``data_received``."""

    transport: asyncio.Transport | None

    def connection_made(self, transport: asyncio.BaseTransport) -> None:
        self.transport = transport  # type: ignore[assignment]

    def get_buffer(self, sizehint: int) -> memoryview:
        return _BUFFER

    def buffer_updated(self, nbytes: int) -> None:
        self.data_received(_BUFFER[:nbytes].tobytes())

    def data_received(self, data: bytes) -> None:
        raise NotImplementedError


class Robot(_SharedBufferClient):
    __slots__ = ("transport", "sent", "carry", "latencies", "answered", "wrong", "closed", "closing")

    def __init__(self, latencies: array) -> None:
        self.transport: asyncio.Transport | None = None
        self.sent: deque[float] = deque()
        self.carry = b""
        self.latencies = latencies
        self.answered = self.wrong = 0
        self.closed = self.closing = False

    def data_received(self, data: bytes) -> None:
        now = perf()
        if self.carry:
            data = self.carry + data
        count = len(data) // ANSWER_LEN
        end = count * ANSWER_LEN
        self.carry = data[end:]
        if data[:end] != ANSWER * count:
            self.wrong += sum(data[i : i + ANSWER_LEN] != ANSWER for i in range(0, end, ANSWER_LEN))
        sent, add = self.sent, self.latencies.append
        for _ in range(min(count, len(sent))):
            add(now - sent.popleft())
        self.answered += count

    def connection_lost(self, exc: Exception | None) -> None:
        self.closed = not self.closing  # closed by the box


async def _connect_all(loop: asyncio.AbstractEventLoop, host: str, port: int, robots: list[Robot]) -> None:
    batch = 100
    for start in range(0, len(robots), batch):
        await asyncio.gather(*[
            loop.create_connection(lambda r=r: r, host, port) for r in robots[start : start + batch]
        ])


async def _stream(host: str, port: int, count: int, rate: float, duration: float, start_at: float,
                  phase_offset: float, phase_total: int) -> dict:
    loop = asyncio.get_running_loop()
    latencies = array("d")
    lags = array("d")
    robots = [Robot(latencies) for _ in range(count)]
    await _connect_all(loop, host, port, robots)
    frames = pose_frames()
    period = 1.0 / rate
    slots = max(1, round(period / 0.001))  # 1 ms buckets
    buckets: list[list[Robot]] = [[] for _ in range(slots)]
    for i, robot in enumerate(robots):  # spread over the period, interleaved with the other workers
        buckets[int(((i * phase_total // max(count, 1)) + phase_offset) % slots)].append(robot)
    tick = period / slots
    sent = 0
    cpu0 = time.process_time()
    await asyncio.sleep(max(0.0, start_at - time.time()))
    t0 = perf()
    end = t0 + duration
    k = 0  # next bucket number (absolute)
    frame_no = 0
    while True:
        due = t0 + k * tick
        if due >= end:
            break
        now = perf()
        if due > now:
            await asyncio.sleep(due - now)
            continue
        # every bucket that is due (a late tick catches up)
        while due <= now and due < end:
            frame = frames[frame_no % len(frames)]
            for robot in buckets[k % slots]:
                transport = robot.transport
                if transport is not None and not robot.closed:
                    robot.sent.append(perf())
                    transport.write(frame)
                    sent += 1
            lags.append(now - due)
            k += 1
            if k % slots == 0:
                frame_no += 1
            due = t0 + k * tick
        await asyncio.sleep(0)
    elapsed = perf() - t0
    # wait for the answers still in flight (bounded: 5 s, the default time_out)
    deadline = perf() + 5.0
    while sum(len(r.sent) for r in robots) and perf() < deadline:
        await asyncio.sleep(0.01)
    for robot in robots:
        robot.closing = True
        if robot.transport is not None:
            robot.transport.close()
    await asyncio.sleep(0.05)
    return {
        "sent": sent,
        "answered": sum(r.answered for r in robots),
        "wrong": sum(r.wrong for r in robots),
        "closed": sum(r.closed for r in robots),
        "elapsed": elapsed,
        "cpu": time.process_time() - cpu0,
        "latencies": latencies.tobytes(),
        "lags": lags.tobytes(),
    }


def _worker(args: tuple, conn) -> None:  # type: ignore[no-untyped-def]
    host, port, count, rate, duration, start_at, offset, total, loop_kind = args
    raise_fd_limit(count + 256)
    loop = new_event_loop(loop_kind)
    try:
        result = loop.run_until_complete(_stream(host, port, count, rate, duration, start_at, offset, total))
    except BaseException as exc:  # report, never hang the parent
        result = {"error": repr(exc)}
    finally:
        loop.close()
    conn.send(result)
    conn.close()


def run_load(box: BoxProcess, robots: int, rate: float, duration: float, procs: int, loop_kind: str) -> dict:
    ctx = multiprocessing.get_context("fork")
    start_at = time.time() + 1.0 + robots / 2000.0  # time to connect everyone
    jobs = []
    per = [robots // procs + (1 if i < robots % procs else 0) for i in range(procs)]
    slots = max(1, round(1000.0 / rate))
    for i, count in enumerate(per):
        parent, child = ctx.Pipe(duplex=False)
        offset = (i * slots) / procs
        p = ctx.Process(
            target=_worker, args=((box.host, box.port, count, rate, duration, start_at, offset, slots, loop_kind), child)
        )
        p.start()
        jobs.append((p, parent))
    cpu0 = box.cpu_seconds()
    results = []
    for p, parent in jobs:
        if parent.poll(duration + 60):
            results.append(parent.recv())
        p.join(10)
        if p.is_alive():
            p.kill()
    cpu1 = box.cpu_seconds()
    errors = [r["error"] for r in results if "error" in r]
    if errors or len(results) != len(jobs):
        raise RuntimeError(f"load generator failed: {errors or 'a worker did not report'}")
    latencies = array("d")
    lags = array("d")
    for r in results:
        latencies.frombytes(r["latencies"])
        lags.frombytes(r["lags"])
    return {
        "sent": sum(r["sent"] for r in results),
        "answered": sum(r["answered"] for r in results),
        "wrong": sum(r["wrong"] for r in results),
        "closed": sum(r["closed"] for r in results),
        "elapsed": max(r["elapsed"] for r in results),
        "latencies": sorted(latencies),
        "lags": sorted(lags),
        "box_cpu": cpu1 - cpu0,
        "gen_cpu": sum(r["cpu"] for r in results),
    }


# -- pipelined ------------------------------------------------------------------------------------------


class Pipe(_SharedBufferClient):
    def __init__(self, chunk: bytes, frames_per_chunk: int, window: int) -> None:
        self.chunk, self.per, self.window = chunk, frames_per_chunk, window
        self.outstanding = self.answered = self.sent = self.wrong = 0
        self.carry = b""
        self.sending = True
        self.transport: asyncio.Transport | None = None
        self.done = asyncio.get_running_loop().create_future()

    def top_up(self) -> None:
        transport = self.transport
        assert transport is not None
        while self.sending and self.outstanding + self.per <= self.window:
            transport.write(self.chunk)
            self.outstanding += self.per
            self.sent += self.per

    def data_received(self, data: bytes) -> None:
        if self.carry:
            data = self.carry + data
        count = len(data) // ANSWER_LEN
        end = count * ANSWER_LEN
        self.carry = data[end:]
        if data[:end] != ANSWER * count:
            self.wrong += 1
        self.answered += count
        self.outstanding -= count
        self.top_up()
        if not self.sending and not self.outstanding and not self.done.done():
            self.done.set_result(None)

    def connection_lost(self, exc: Exception | None) -> None:
        if not self.done.done():
            self.done.set_result(None)


async def _pipelined(host: str, port: int, duration: float, window: int, per_chunk: int) -> dict:
    loop = asyncio.get_running_loop()
    frames = pose_frames(per_chunk)
    chunk = b"".join(frames)
    _, pipe = await loop.create_connection(lambda: Pipe(chunk, per_chunk, window), host, port)
    pipe.transport.get_extra_info("socket").setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 1 << 20)
    t0 = perf()
    pipe.top_up()
    samples = []
    while perf() - t0 < duration:
        await asyncio.sleep(0.25)
        samples.append((perf() - t0, pipe.answered))
    answered_at_end, elapsed = pipe.answered, perf() - t0
    pipe.sending = False
    with contextlib.suppress(asyncio.TimeoutError):
        await asyncio.wait_for(pipe.done, 5.0)
    pipe.transport.close()
    return {"sent": pipe.sent, "answered": pipe.answered, "wrong": pipe.wrong, "rate": answered_at_end / elapsed,
            "samples": samples}


# -- main ----------------------------------------------------------------------------------------------------


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robots", type=int, default=100, help="concurrent robots (default 100)")
    parser.add_argument("--rate", type=float, default=50.0, help="poses per second per robot (default 50)")
    parser.add_argument("--duration", type=float, default=10.0, help="seconds of streaming (default 10, max 120)")
    parser.add_argument("--procs", type=int, default=1, help="load generator processes (default 1)")
    parser.add_argument("--pipelined", action="store_true", help="one connection, as fast as possible")
    parser.add_argument("--window", type=int, default=16384, help="pipelined: frames in flight (default 16384)")
    parser.add_argument("--chunk", type=int, default=512, help="pipelined: frames per write (default 512)")
    parser.add_argument("--box-loop", choices=("asyncio", "uvloop"), default="asyncio", help="the box's event loop")
    parser.add_argument("--gen-loop", choices=("asyncio", "uvloop"), default="asyncio",
                        help="the load generator's event loop")
    parser.add_argument("--box-arg", action="append", default=[], metavar="ARG",
                        help="extra argument for 'serve' (repeatable), e.g. --box-arg=--latency-ms=1")
    args = parser.parse_args()
    if not 0 < args.duration <= 120:
        parser.error("--duration must be in (0, 120]")
    if args.robots < 1 or args.procs < 1 or args.rate <= 0:
        parser.error("--robots, --procs and --rate must be positive")
    raise_fd_limit(args.robots + 256)
    box_args = ["--no-udp", "--idle-timeout", "0", "--max-connections", str(max(2000, args.robots + 100)),
                "--loop", args.box_loop, *args.box_arg]
    load_before = os.getloadavg()[0]
    with BoxProcess(*box_args) as box:
        print(f"box: pid {box.pid}, {box.command}")
        if args.pipelined:
            loop = new_event_loop(args.gen_loop)
            try:
                r = loop.run_until_complete(_pipelined(box.host, box.port, args.duration, args.window, args.chunk))
            finally:
                loop.close()
            mem = box.memory()
            print(f"pipelined: 1 connection, window {args.window} frames, {args.chunk} frames per write, "
                  f"{args.duration:g} s")
            print(f"  answered {r['answered']} of {r['sent']} sent; wrong answers: {r['wrong']}")
            print(f"  answered frames/s: {r['rate']:,.0f}")
            print(f"  box RSS: peak {mem.get('VmHWM', 0) / 1024:.1f} MB, now {mem.get('VmRSS', 0) / 1024:.1f} MB")
            ok = r["wrong"] == 0
        else:
            r = run_load(box, args.robots, args.rate, args.duration, args.procs, args.gen_loop)
            mem = box.memory()
            lat, lags = r["latencies"], r["lags"]
            lost = r["sent"] - r["answered"]
            ms = 1000.0
            print(f"load: {args.robots} robots x {args.rate:g} Hz = {args.robots * args.rate:,.0f} frames/s offered, "
                  f"{args.duration:g} s, {args.procs} generator process(es), generator loop {args.gen_loop}")
            print(f"  sent {r['sent']}, answered {r['answered']}, lost {lost}, wrong {r['wrong']}, "
                  f"connections closed by the box {r['closed']}")
            print(f"  answered frames/s: {r['answered'] / r['elapsed']:,.0f}")
            print(f"  answer latency ms: p50 {percentile(lat, 50) * ms:.2f}  p99 {percentile(lat, 99) * ms:.2f}  "
                  f"p99.9 {percentile(lat, 99.9) * ms:.2f}  max {lat[-1] * ms if lat else float('nan'):.2f}")
            print(f"  generator send lag ms: p50 {percentile(lags, 50) * ms:.2f}  p99 {percentile(lags, 99) * ms:.2f}  "
                  f"max {lags[-1] * ms if lags else float('nan'):.2f}")
            print(f"  CPU: box {r['box_cpu'] / r['elapsed'] * 100:.0f}%, load generator "
                  f"{r['gen_cpu'] / r['elapsed'] * 100:.0f}% of one core")
            print(f"  box RSS: peak {mem.get('VmHWM', 0) / 1024:.1f} MB, now {mem.get('VmRSS', 0) / 1024:.1f} MB")
            ok = lost == 0 and r["wrong"] == 0
        summary = box.stop()
        print(f"  box: {summary.splitlines()[-1] if summary else '(no summary)'}")
    print(f"  machine load average (1 min): {load_before:.2f} before, {os.getloadavg()[0]:.2f} after "
          f"({os.cpu_count()} cores; other processes skew the figures)")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())

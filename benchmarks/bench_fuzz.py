"""Fuzz examples per second against the bundled box, with and without pcap evidence.

Run on demand: ``python benchmarks/bench_fuzz.py [--seconds S] [--seed N]``. The box is
``python -m conformance serve --port 0 --no-udp`` in a child process. In the same run,
one after the other, for ``--seconds`` each:

* **baseline**: a raw socket ping-pong on one connection (send a 14-byte NONE frame,
  read its 14-byte answer), the ceiling for one request/answer round trip;
* **generation only**: hypothesis drawing the same fuzz cases (batches of up to 32)
  with no I/O at all: what hypothesis and the oracle's expectations cost;
* **fuzz**: a frame campaign (``stateful_share=0``) where every example is a fuzz case
  plus its probe, judged by the oracle, with a liveness check on a fresh connection
  every 64 cases and after every anomaly; pcaps only for failures (none here);
* **fuzz + pcap**: the same with ``capture="all"``: every packet of the campaign
  written to pcapng as it happens.

It prints the rates side by side, the cost of the pcap evidence, and the machine's
load average (other processes skew the figures: run it twice).
"""

from __future__ import annotations

import argparse
import os
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from hypothesis import HealthCheck, Phase, given, seed, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402

from conformance.fuzz.campaign import Campaign, CampaignConfig  # noqa: E402
from conformance.fuzz.strategies import Strategies  # noqa: E402
from conformance.harness.target import Target  # noqa: E402
from conformance.protocol import Profile  # noqa: E402

NONE = bytes.fromhex("fefe000101000000000000000000")


def start_box() -> tuple[subprocess.Popen[str], int]:
    proc = subprocess.Popen(
        [sys.executable, "-m", "conformance", "serve", "--host", "127.0.0.1", "--port", "0", "--no-udp",
         "--idle-timeout", "0"],
        stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True,
    )
    assert proc.stdout is not None
    line = proc.stdout.readline()  # "listening tcp 127.0.0.1:PORT"
    if not line.startswith("listening tcp "):
        proc.kill()
        raise SystemExit(f"the box did not start: {line!r}")
    return proc, int(line.split()[2].rsplit(":", 1)[1])


def baseline(port: int, seconds: float) -> float:
    with socket.create_connection(("127.0.0.1", port)) as s:
        s.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        n, end = 0, time.perf_counter() + seconds
        start = time.perf_counter()
        while time.perf_counter() < end:
            for _ in range(100):
                s.sendall(NONE)
                got = 0
                while got < 14:
                    got += len(s.recv(65536))
            n += 100
        return n / (time.perf_counter() - start)


def generation_only(seconds: float, seed_value: int) -> float:
    """Cases/s hypothesis draws (with the oracle's expectations) in chunks of 100 examples, as a campaign does."""
    cases = st.lists(Strategies(Profile()).cases(), min_size=1, max_size=32)
    count = [0]
    start = time.perf_counter()
    end = start + seconds
    chunk = 0

    def draw(batch: list[object]) -> None:
        count[0] += len(batch)

    while time.perf_counter() < end:
        test = seed(seed_value * 1_000_003 + chunk)(settings(
            max_examples=100, database=None, deadline=None, phases=[Phase.generate],
            suppress_health_check=list(HealthCheck))(given(cases)(draw)))
        test()
        chunk += 1
    return count[0] / (time.perf_counter() - start)


def campaign(port: int, seconds: float, seed_value: int, capture: str, tmp: Path) -> dict[str, object]:
    config = CampaignConfig(
        target=Target("127.0.0.1", port), seed=seed_value, duration_s=seconds, stateful_share=0,
        report_dir=tmp / f"report-{capture}", pcap_dir=tmp / f"pcaps-{capture}", capture=capture, log=lambda _: None,
    )
    summary = Campaign(config).run().to_dict()
    size = sum(p.stat().st_size for p in (tmp / f"pcaps-{capture}").glob("*.pcapng")) if capture == "all" else 0
    summary["pcap_bytes"] = size
    return summary


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--seconds", type=float, default=5.0, help="per measurement (default: 5)")
    ap.add_argument("--seed", type=int, default=1)
    args = ap.parse_args()
    load_before = os.getloadavg()[0]
    proc, port = start_box()
    try:
        with tempfile.TemporaryDirectory() as d:
            tmp = Path(d)
            base = baseline(port, args.seconds)
            gen = generation_only(args.seconds, args.seed)
            plain = campaign(port, args.seconds, args.seed, "failures", tmp)
            pcap = campaign(port, args.seconds, args.seed, "all", tmp)
    finally:
        proc.terminate()
        proc.wait(10)
    rate_plain = float(plain["examples_per_s"] or 0)  # type: ignore[arg-type]
    rate_pcap = float(pcap["examples_per_s"] or 0)  # type: ignore[arg-type]
    print(f"box: pid {proc.pid}, python -m conformance serve --port 0 --no-udp (child process), {args.seconds:g} s each")
    print(f"  baseline raw socket ping-pong (NONE, 14 B each way): {base:>10,.0f} round trips/s")
    print(f"  hypothesis generation only (no I/O):                 {gen:>10,.0f} cases/s")
    print(f"  fuzz, oracle + liveness, pcaps for failures only:    {rate_plain:>10,.0f} examples/s "
          f"({plain['examples']:,} examples, {plain['liveness_checks']:,} liveness checks, "
          f"{len(plain['failures'])} failures)")  # type: ignore[arg-type]
    print(f"  fuzz, oracle + liveness, every packet to pcapng:      {rate_pcap:>10,.0f} examples/s "
          f"({pcap['examples']:,} examples, {int(pcap['pcap_bytes']) / 1e6:.1f} MB of pcapng)")  # type: ignore[call-overload]
    if rate_plain:
        print(f"  pcap evidence costs {100 * (1 - rate_pcap / rate_plain):.1f} % of the examples/s")
    print(f"  machine load average (1 min): {load_before:.2f} before, {os.getloadavg()[0]:.2f} after "
          f"({os.cpu_count()} cores; other processes skew the figures)")


if __name__ == "__main__":
    main()

"""Fuzz cases per second against the bundled box, beside boofuzz on the same box in the same run.

Run on demand: ``python benchmarks/bench_fuzz.py [--seconds S] [--repeats R] [--seed N]``. The
box is ``python -m conformance serve --port 0 --no-udp`` in a child process. In the same run:

* **baseline**: a raw socket ping-pong on one connection (send a 14-byte NONE frame,
  read its 14-byte answer), the ceiling for one request/answer round trip;
* **generation only**: hypothesis drawing the same fuzz cases (batches of up to 32)
  with no I/O at all: what hypothesis and the oracle's expectations cost;
* then ``--repeats`` rounds, each one tool after the other, back to back, for
  ``--seconds`` each (the machine's load moves between rounds, not within one):
  - **fuzz**: a campaign as ``fuzz`` runs it (session share 0.2, the schedule, the
    mutants of :mod:`conformance.fuzz.mutants`): every case plus its probe judged by
    the oracle, liveness on a fresh connection every 64 cases and after every anomaly;
    its rate is every case it sent (frame cases and session steps) per second;
  - **fuzz, frames only**: the same without sessions (``stateful_share=0``);
  - **fuzz, no mutants**: sessions 0.2, every frame case drawn by hypothesis or the
    schedule (``mutants=0``: the campaign's loop of the previous release);
  - **boofuzz**: ``benchmarks/boofuzz_isight.py`` (its cases/s, a new connection each);
* **fuzz + pcap**: once, frames only with ``capture="all"``.

It prints each round, the medians, fuzz's median over boofuzz's, and the machine's
load average (other processes skew the figures: compare within a run).
"""

from __future__ import annotations

import argparse
import json
import os
import socket
import statistics
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


#: The previous release's figures on this machine (issue 28: one tool at a time in the same session).
PREVIOUS = {"fuzz": 752.0, "boofuzz": 559.0}
HERE = Path(__file__).resolve().parent


def campaign(port: int, seconds: float, seed_value: int, capture: str, tmp: Path, *, share: float = 0.0,
             mutants: int | None = None, name: str = "") -> dict[str, object]:
    """One campaign's summary, with ``cases_per_s``: every case it sent (frames and session steps) per second."""
    tag = name or capture
    extra = {} if mutants is None else {"mutants": mutants}
    config = CampaignConfig(
        target=Target("127.0.0.1", port), seed=seed_value, duration_s=seconds, stateful_share=share,
        report_dir=tmp / f"report-{tag}", pcap_dir=tmp / f"pcaps-{tag}", capture=capture, log=lambda _: None,
        database=None, **extra,  # type: ignore[arg-type]
    )
    summary = Campaign(config).run().to_dict()
    size = sum(p.stat().st_size for p in (tmp / f"pcaps-{tag}").glob("*.pcapng")) if capture == "all" else 0
    summary["pcap_bytes"] = size
    steps = int(summary["stateful"]["steps"])  # type: ignore[index]
    summary["cases_per_s"] = (int(summary["examples"]) + steps) / float(summary["duration_s"])  # type: ignore[call-overload, arg-type]
    return summary


def boofuzz(port: int, seconds: float, tmp: Path) -> float | None:
    """boofuzz's cases/s against the box (``boofuzz_isight.py`` in a child process; None: boofuzz is missing)."""
    out = tmp / "boofuzz.json"
    out.unlink(missing_ok=True)
    done = subprocess.run([sys.executable, str(HERE / "boofuzz_isight.py"), "--port", str(port), "--duration",
                           str(seconds), "--result", str(out)], capture_output=True, text=True,
                          timeout=seconds * 4 + 60, check=False)
    if not out.exists():
        print(f"  boofuzz did not run: {(done.stderr or done.stdout).strip().splitlines()[-1:]}")
        return None
    return float(json.loads(out.read_text())["cases_per_s"] or 0)


def rounds(port: int, args: argparse.Namespace, tmp: Path) -> dict[str, list[float]]:
    """``--repeats`` rounds of the four tools back to back; each tool's rates."""
    rates: dict[str, list[float]] = {"fuzz": [], "frames": [], "no-mutants": [], "boofuzz": []}
    for r in range(args.repeats):
        seed_value = args.seed + r
        full = campaign(port, args.seconds, seed_value, "failures", tmp, share=0.2, name=f"full-{r}")
        frames = campaign(port, args.seconds, seed_value, "failures", tmp, name=f"frames-{r}")
        plain = campaign(port, args.seconds, seed_value, "failures", tmp, share=0.2, mutants=0, name=f"plain-{r}")
        boo = boofuzz(port, args.seconds, tmp)
        for key, value in (("fuzz", full["cases_per_s"]), ("frames", frames["cases_per_s"]),
                           ("no-mutants", plain["cases_per_s"])):
            rates[key].append(float(value))  # type: ignore[arg-type]
        if boo is not None:
            rates["boofuzz"].append(boo)
        states = full["stateful"]["coverage"].get("fraction")  # type: ignore[index]
        before = plain["stateful"]["coverage"].get("fraction")  # type: ignore[index]
        print(f"  round {r + 1}: fuzz {full['cases_per_s']:,.0f}/s (states {states}, coverage "
              f"{full['coverage']['fraction']}), frames only {frames['cases_per_s']:,.0f}/s, "  # type: ignore[index]
              f"no mutants {plain['cases_per_s']:,.0f}/s (states {before}, coverage "
              f"{plain['coverage']['fraction']}), boofuzz {boo or 0:,.0f}/s; "  # type: ignore[index]
              f"failures {len(full['failures']) + len(frames['failures']) + len(plain['failures'])}; "  # type: ignore[arg-type]
              f"load {os.getloadavg()[0]:.1f}", flush=True)
    return rates


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--seconds", type=float, default=5.0, help="per measurement (default: 5)")
    ap.add_argument("--repeats", type=int, default=3, help="rounds of the tools back to back (default: 3)")
    ap.add_argument("--seed", type=int, default=1)
    args = ap.parse_args()
    load_before = os.getloadavg()[0]
    proc, port = start_box()
    print(f"box: pid {proc.pid}, python -m conformance serve --port 0 --no-udp (child process), {args.seconds:g} s "
          f"each, {args.repeats} rounds", flush=True)
    try:
        with tempfile.TemporaryDirectory() as d:
            tmp = Path(d)
            base = baseline(port, args.seconds)
            gen = generation_only(args.seconds, args.seed)
            rates = rounds(port, args, tmp)
            pcap = campaign(port, args.seconds, args.seed, "all", tmp)
    finally:
        proc.terminate()
        proc.wait(10)
    med = {k: statistics.median(v) if v else 0.0 for k, v in rates.items()}
    print(f"  baseline raw socket ping-pong (NONE, 14 B each way): {base:>10,.0f} round trips/s")
    print(f"  hypothesis generation only (no I/O):                 {gen:>10,.0f} cases/s")
    print(f"  median of {args.repeats} rounds, cases/s:")
    print(f"    fuzz (sessions 0.2, schedule, mutants):          {med['fuzz']:>10,.0f}")
    print(f"    fuzz, frames only:                               {med['frames']:>10,.0f}")
    print(f"    fuzz, no mutants (the previous release's loop):  {med['no-mutants']:>10,.0f}")
    print(f"    boofuzz (boofuzz_isight.py):                     {med['boofuzz']:>10,.0f}")
    if med["boofuzz"]:
        print(f"  fuzz / boofuzz: {med['fuzz'] / med['boofuzz']:.2f}x (previous release: {PREVIOUS['fuzz']:,.0f} vs "
              f"{PREVIOUS['boofuzz']:,.0f} cases/s, {PREVIOUS['fuzz'] / PREVIOUS['boofuzz']:.2f}x)")
    rate_pcap = float(pcap["cases_per_s"])  # type: ignore[arg-type]
    print(f"  fuzz, frames only, every packet to pcapng:         {rate_pcap:>10,.0f} cases/s "
          f"({int(pcap['pcap_bytes']) / 1e6:.1f} MB of pcapng)")  # type: ignore[call-overload]
    print(f"  machine load average (1 min): {load_before:.2f} before, {os.getloadavg()[0]:.2f} after "
          f"({os.cpu_count()} cores; other processes skew the figures)")


if __name__ == "__main__":
    main()

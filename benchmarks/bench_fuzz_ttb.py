"""Time to bug: how long ``fuzz`` takes to find each planted defect of ``ttb_box.py``, over several seeds, beside boofuzz.

Run on demand (minutes; the machine's load skews the seconds, not the found/not-found):

    python benchmarks/bench_fuzz_ttb.py --duration 60 --seeds 3 [--defects count7-crash,udp-wrong]
        [--boofuzz-seeds 1 | --no-boofuzz] [--json out.json]

For every defect of ``benchmarks/ttb_box.py`` (and the clean box: false alarms) and
every seed, a fresh box, then ``isight-conformance fuzz --duration D --seed S
--max-failures 1 --restart-cmd ...`` (the box restarts itself with the same defect)
as a new user would run it, with a UDP target. A defect is *found* when the campaign
reports a failure and the box says the defect fired. Then the reproducer is replayed
against a fresh box: the vector file (``replay``) or, for a session failure, its
sequence file (``run --sequence``). boofuzz (``benchmarks/boofuzz_isight.py``) gets the
same box and budget. Prints, per defect: found k/n, median and max seconds to the
first finding, the clause named, whether the reproducer replays, and boofuzz's figures.
"""

from __future__ import annotations

import argparse
import json
import shlex
import socket
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

HERE = Path(__file__).resolve().parent
BOX = HERE / "ttb_box.py"
sys.path.insert(0, str(HERE))

from ttb_box import DEFECTS  # noqa: E402

CLI = [sys.executable, "-m", "conformance"]


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


class Box:
    def __init__(self, defect: str, tmp: Path) -> None:
        self.port = free_port()
        self.pidfile = tmp / "box.pid"
        self.fired = tmp / "fired"
        cmd = [sys.executable, str(BOX), "--port", str(self.port), "--defect", defect, "--fired", str(self.fired),
               "--udp", "--restart", "--pidfile", str(self.pidfile)]
        self.restart_cmd = " ".join(shlex.quote(c) for c in cmd)

    def start(self) -> None:
        self.fired.unlink(missing_ok=True)
        subprocess.run(self.restart_cmd, shell=True, check=True, timeout=60)  # noqa: S602

    def stop(self) -> None:
        try:
            subprocess.run(["kill", "-9", self.pidfile.read_text().strip()], capture_output=True, timeout=10)
        except (OSError, subprocess.SubprocessError):
            pass

    @property
    def did_fire(self) -> bool:
        return self.fired.exists() and self.fired.stat().st_size > 0


def run_fuzz(defect: str, seed: int, duration: float, tmp: Path) -> dict[str, Any]:
    box = Box(defect, tmp)
    box.start()
    target = f"127.0.0.1:{box.port}"
    cmd = [*CLI, "fuzz", "--target", target, "--udp-target", target, "--duration", str(duration), "--seed", str(seed),
           "--max-failures", "1", "--restart-cmd", box.restart_cmd, "--report-dir", str(tmp / "r"),
           "--pcap-dir", str(tmp / "p"), "--database", "none", "--quiet", "--capture", "off"]
    try:
        subprocess.run(cmd, capture_output=True, text=True, timeout=duration * 3 + 120)
        summary = json.loads((tmp / "r" / "fuzz-summary.json").read_text())
    except (subprocess.TimeoutExpired, OSError, ValueError) as exc:
        box.stop()
        return {"found": False, "error": f"{type(exc).__name__}: {exc}"}
    fired = box.did_fire
    box.stop()
    out: dict[str, Any] = {"found": False, "rate": summary.get("examples_per_s"),
                           "coverage": summary.get("coverage", {}).get("fraction"),
                           "states": summary.get("stateful", {}).get("coverage", {}).get("fraction")}
    failures = summary["failures"]
    if failures:
        f = failures[0]
        out.update(found=fired or defect == "clean", seconds=f["found_s"], clause=",".join(f["clauses"][:2]),
                   kind=f["kind"], confirmed=f["confirmed"], cases=len(f["cases"]))
        out["replays"] = replays(box, f, tmp)
    return out


def replays(box: Box, failure: dict[str, Any], tmp: Path) -> bool:
    """Does the reproducer fail against a fresh box?"""
    box.start()
    target = f"127.0.0.1:{box.port}"
    try:
        if failure.get("sequence"):
            cmd = [*CLI, "run", "--target", target, "--sequence", failure["sequence"], "--cases", "SEQ-FUZZ-*",
                   "--report-dir", str(tmp / "seq"), "--pcap-dir", str(tmp / "seqp")]
        elif failure.get("vector"):
            cmd = [*CLI, "replay", failure["vector"], "--target", target, "--udp-target", target]
        else:
            return False
        done = subprocess.run(cmd, capture_output=True, text=True, timeout=180)
        return done.returncode == 1
    except subprocess.TimeoutExpired:
        return False
    finally:
        box.stop()


def run_boofuzz(defect: str, duration: float, tmp: Path) -> dict[str, Any]:
    box = Box(defect, tmp)
    box.start()
    res = tmp / "boofuzz.json"
    cmd = [sys.executable, str(HERE / "boofuzz_isight.py"), "--port", str(box.port), "--duration", str(duration),
           "--result", str(res), "--pidfile", str(box.pidfile)]
    try:
        subprocess.run(cmd, capture_output=True, text=True, timeout=duration * 2 + 60)
        doc = json.loads(res.read_text())
    except (subprocess.TimeoutExpired, OSError, ValueError) as exc:
        return {"found": False, "error": f"{type(exc).__name__}: {exc}"}
    finally:
        fired = box.did_fire
        box.stop()
    found = doc["found_s"] is not None and (fired or defect == "clean")
    return {"found": found, "seconds": doc["found_s"] if found else None, "rate": doc.get("cases_per_s")}


def row(defect: str, runs: list[dict[str, Any]], peers: list[dict[str, Any]]) -> str:
    found = [r for r in runs if r["found"]]
    secs = [r["seconds"] for r in found]
    med = f"{statistics.median(secs):6.1f}" if secs else "     -"
    mx = f"{max(secs):6.1f}" if secs else "     -"
    clause = found[0]["clause"] if found else "-"
    rep = f"{sum(bool(r.get('replays')) for r in found)}/{len(found)}" if found else "-"
    peer = "not run"
    if peers:
        pf = [p["seconds"] for p in peers if p["found"]]
        peer = f"{len(pf)}/{len(peers)}" + (f", median {statistics.median(pf):.1f} s" if pf else "")
    return f"| {defect:<17} | {len(found)}/{len(runs)} | {med} | {mx} | {clause:<9} | {rep:<7} | {peer} |"


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--duration", type=float, default=60.0)
    p.add_argument("--seeds", type=int, default=3)
    p.add_argument("--boofuzz-seeds", type=int, default=1, help="boofuzz runs per defect (it has no seed: repeats)")
    p.add_argument("--no-boofuzz", action="store_true")
    p.add_argument("--defects", help="comma-separated (default: all, and the clean box)")
    p.add_argument("--json", help="write every run's figures here")
    args = p.parse_args()
    defects = args.defects.split(",") if args.defects else [*DEFECTS, "clean"]
    print(f"time to bug: fuzz --duration {args.duration:g}, {args.seeds} seeds, stop at the first finding; "
          f"boofuzz {'off' if args.no_boofuzz else f'{args.boofuzz_seeds} run(s)'}", flush=True)
    print("| defect            | found | median s | max s | clause    | replays | boofuzz (found, median s) |")
    print("|---|---|---|---|---|---|---|", flush=True)
    every: dict[str, Any] = {}
    for defect in defects:
        runs, peers = [], []
        for seed in range(1, args.seeds + 1):
            with tempfile.TemporaryDirectory(prefix="ttb-") as tmp:
                runs.append(run_fuzz(defect, seed, args.duration, Path(tmp)))
        if not args.no_boofuzz:
            for _ in range(args.boofuzz_seeds):
                with tempfile.TemporaryDirectory(prefix="ttb-boo-") as tmp:
                    peers.append(run_boofuzz(defect, args.duration, Path(tmp)))
        every[defect] = {"fuzz": runs, "boofuzz": peers}
        print(row(defect, runs, peers), flush=True)
    if args.json:
        Path(args.json).write_text(json.dumps(every, indent=1))
    print(f"load average: {' '.join(f'{x:.1f}' for x in __import__('os').getloadavg())}; {time.strftime('%H:%M:%S')}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

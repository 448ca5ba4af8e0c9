"""The soak's own memory beside the box's: is ``isight-conformance soak`` bounded itself (issue 38)?

Run on demand: ``python benchmarks/bench_soak.py [--duration 2m] [--window 10s] [--robots 2]
[--cycle-s 1] [--events 0.1] [--target HOST:PORT --box-pid PID] [--keep DIR]``.

One soak in a child process, against the bundled reference box (a child of the soak, watched with
psutil) unless ``--target`` names another. The soak records, per window, its own RSS and the box's;
this script prints them side by side, then the Theil–Sen slope of each per hour (95 % interval) and
the first and last values after the first tenth of the windows (warm-up). The issue's figure is a
30-minute soak: ``--duration 30m --window 60s``. The default (two minutes) is a smoke test.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from conformance.soak.trend import theil_sen  # noqa: E402


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--duration", default="2m")
    parser.add_argument("--window", default="10s")
    parser.add_argument("--robots", default="2")
    parser.add_argument("--cycle-s", default="1")
    parser.add_argument("--events", default="0.1")
    parser.add_argument("--target")
    parser.add_argument("--box-pid")
    parser.add_argument("--keep", metavar="DIR", help="keep the soak's report directory here")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as scratch:
        tmp = args.keep or scratch
        cmd = [sys.executable, "-m", "conformance", "soak", "--duration", args.duration, "--window", args.window,
               "--robots", args.robots, "--cycle-s", args.cycle_s, "--events", args.events, "--stall-s", "0.5",
               "--report-dir", tmp, "--quiet"]
        if args.target:
            cmd += ["--target", args.target]
        if args.box_pid:
            cmd += ["--box-pid", args.box_pid]
        started = time.monotonic()
        proc = subprocess.run(cmd, cwd=ROOT, env={**os.environ, "PYTHONPATH": str(ROOT)}, capture_output=True,
                              text=True)
        wall = time.monotonic() - started
        path = Path(tmp) / "soak.json"
        if not path.exists():
            print(proc.stdout + proc.stderr)
            return 1
        doc = json.loads(path.read_text())
    rows = doc["windows"]
    print(f"soak {doc['elapsed_s']:.0f} s (wall {wall:.0f} s), {doc['totals']['sessions']:,} sessions, "
          f"{len(rows)} windows, events {doc['totals']['events']}; overall {doc['overall']}")
    print(f"{'window':>6} {'end s':>7} {'sessions':>8} {'soak RSS MB':>12} {'box RSS MB':>11} {'box fds':>8}")
    for r in rows:
        res = r["resources"]
        print(f"{r['index']:>6} {r['end_s']:>7.0f} {r['sessions_total']:>8} {res.get('soak_rss_mb', 0):>12.2f} "
              f"{res.get('rss_mb') or 0:>11.2f} {res.get('fds') or 0:>8.0f}")
    skip = max(1, len(rows) // 10)
    for key, name in (("soak_rss_mb", "soak"), ("rss_mb", "box")):
        pts = [((r["start_s"] + r["end_s"]) / 7200, r["resources"][key]) for r in rows[skip:]
               if r["resources"].get(key) is not None]
        if len(pts) >= 3:
            fit = theil_sen([p[0] for p in pts], [p[1] for p in pts])
            print(f"{name} RSS after warm-up: {pts[0][1]:.2f} → {pts[-1][1]:.2f} MB, max "
                  f"{max(p[1] for p in pts):.2f} MB; Theil–Sen {fit.slope:+.2f} MB/h "
                  f"(95 % CI {fit.low:+.2f} … {fit.high:+.2f})")
    return 0


if __name__ == "__main__":
    sys.exit(main())

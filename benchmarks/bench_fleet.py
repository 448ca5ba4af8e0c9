"""Fleet runs: wall time for 1, 3 and 6 bundled boxes with ``--jobs 1`` and ``--jobs 3``.

Run on demand: ``python benchmarks/bench_fleet.py [--boxes 1,3,6] [--jobs 1,3] [--cases GLOB]``;
``--xdist`` instead measures pytest-xdist over two boxes: the cases against two bundled
reference boxes (``--target`` twice) serially, then with ``pytest -n 2``.
Each measurement is one ``isight-conformance run --targets FILE --jobs J --quiet`` in a
child process, on a fleet file of N boxes without a ``target`` (each box's run starts
its own bundled reference box on loopback), the full suite unless ``--cases`` narrows
it. It prints the wall time, the sum of the boxes' own durations, whether the fleet
passed, and the speed-up of ``--jobs 3`` over ``--jobs 1`` for each fleet size. The
machine's load average before and after is printed too: the figures measure the
machine as much as the suite.
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


def fleet_file(path: Path, boxes: int) -> Path:
    path.write_text("".join(f'[[box]]\nname = "box-{i + 1}"\n\n' for i in range(boxes)), encoding="utf-8")
    return path


def measure(workdir: Path, boxes: int, jobs: int, cases: list[str], timeout: float) -> dict:
    fleet = fleet_file(workdir / f"fleet-{boxes}.toml", boxes)
    out = workdir / f"out-{boxes}-{jobs}"
    cmd = [sys.executable, "-m", "conformance", "run", "--targets", str(fleet), "--jobs", str(jobs),
           "--report-dir", str(out), "--quiet", *[f"--cases={c}" for c in cases]]
    start = time.monotonic()
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout, cwd=workdir)
    wall = time.monotonic() - start
    doc = json.loads((out / "fleet.json").read_text())
    per_box = [b["duration_s"] or 0.0 for b in doc["boxes"]]
    return {"boxes": boxes, "jobs": jobs, "wall_s": wall, "sum_s": sum(per_box), "max_box_s": max(per_box),
            "passed": doc["passed"], "exit": proc.returncode,
            "statuses": ", ".join(f"{k} {v}" for k, v in doc["counts"].items())}


def xdist_speedup(workdir: Path, cases: list[str], timeout: float) -> None:
    """Two boxes, every case against each: serial pytest, then ``pytest -n 2`` (one box per worker)."""
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
    from conformance.endpoints.bundled import start_bundled
    from conformance.protocol import Profile

    boxes = [start_bundled(Profile()), start_bundled(Profile())]
    try:
        walls = {}
        for label, extra in (("serial", []), ("pytest -n 2", ["-n", "2"])):
            cmd = [sys.executable, "-m", "pytest", "--pyargs", "conformance.cases", "-q", "-p", "no:cacheprovider",
                   "--report-dir", str(workdir / label.replace(" ", "")), *extra,
                   *[a for b in boxes for a in ("--target", str(b.target))], *[f"--cases={c}" for c in cases]]
            start = time.monotonic()
            proc = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout, cwd=workdir)
            walls[label] = time.monotonic() - start
            tail = proc.stdout.strip().splitlines()[-1] if proc.stdout.strip() else proc.stderr[-200:]
            print(f"2 boxes, {label}: wall {walls[label]:.1f} s (exit {proc.returncode}: {tail})", flush=True)
        ratio = walls["pytest -n 2"] / walls["serial"]
        print(f"pytest -n 2 over 2 boxes: {ratio:.2f}× the serial time ({1 / ratio:.2f}× faster)")
    finally:
        for box in boxes:
            box.stop()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--boxes", default="1,3,6", help="fleet sizes, comma-separated (default 1,3,6)")
    ap.add_argument("--jobs", default="1,3", help="--jobs values, comma-separated (default 1,3)")
    ap.add_argument("--cases", action="append", default=[], metavar="GLOB",
                    help="only these cases (repeatable; default: the whole suite)")
    ap.add_argument("--timeout", type=float, default=1800, help="give up on one fleet run after S seconds")
    ap.add_argument("--xdist", action="store_true", help="measure pytest -n 2 over two boxes instead of fleets")
    args = ap.parse_args()
    if args.xdist:
        print(f"load average before: {' '.join(f'{x:.2f}' for x in os.getloadavg())}; {os.cpu_count()} CPUs")
        with tempfile.TemporaryDirectory(prefix="bench-xdist-") as tmp:
            xdist_speedup(Path(tmp), args.cases, args.timeout)
        print(f"load average after: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")
        return
    sizes = [int(x) for x in args.boxes.split(",")]
    jobs_list = [int(x) for x in args.jobs.split(",")]
    print(f"load average before: {' '.join(f'{x:.2f}' for x in os.getloadavg())}; {os.cpu_count()} CPUs", flush=True)
    results = []
    with tempfile.TemporaryDirectory(prefix="bench-fleet-") as tmp:
        for boxes in sizes:
            for jobs in jobs_list:
                r = measure(Path(tmp), boxes, jobs, args.cases, args.timeout)
                results.append(r)
                print(f"{boxes} boxes, --jobs {jobs}: wall {r['wall_s']:6.1f} s; boxes' own durations sum "
                      f"{r['sum_s']:6.1f} s, longest {r['max_box_s']:5.1f} s; "
                      f"{'PASS' if r['passed'] else 'FAIL'} ({r['statuses']})", flush=True)
    print(f"load average after: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")
    if len(jobs_list) < 2:
        return
    print()
    print("| boxes | " + " | ".join(f"--jobs {j}" for j in jobs_list) + f" | --jobs {jobs_list[-1]} vs {jobs_list[0]} |")
    print("|---|" + "---|" * len(jobs_list) + "---|")
    for boxes in sizes:
        row = {r["jobs"]: r for r in results if r["boxes"] == boxes}
        cells = [f"{row[j]['wall_s']:.1f} s" for j in jobs_list]
        first, last = row[jobs_list[0]]["wall_s"], row[jobs_list[-1]]["wall_s"]
        print(f"| {boxes} | " + " | ".join(cells) + f" | {last / first:.2f}× the time ({first / last:.2f}× faster) |")


if __name__ == "__main__":
    main()

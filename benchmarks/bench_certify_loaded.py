"""certify-robot on a loaded runner: the conforming robots of ``tests/impls`` certified while CPU hogs run.

Run on demand: ``python benchmarks/bench_certify_loaded.py [--rounds 3] [--hogs 2] [--out DIR]``.

One quiet round (no hogs) is the baseline; then ``--hogs`` busy-loop processes run throughout
``--rounds`` loaded rounds. A round certifies each conforming robot (``canonical``,
``karel-calls``, ``extension``: S1, the source's own calls, E4 with no flag) once, one at a
time, at the default settings (tolerances, answer latencies), as a user would run it. The robots
are legal: every FAIL is a false alarm. For each robot the table gives the runs, the runs with a
FAIL, the cases that failed, the INCONCLUSIVEs that name a starved tester, the FAILs whose report
says the robot's own starvation could explain them, and the median and worst wall time of a
certification (the suite's own ``duration_s``; the limit is 15 s). The load average before and
after is printed too.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from conformance.certify.robot_starvation import ROBOT_STARVED  # noqa: E402
from tests.impls.expectations import EXPECTATIONS  # noqa: E402
from tests.impls.matrix import run_robot  # noqa: E402

ROBOTS = ("canonical", "karel-calls", "extension")


def hog() -> subprocess.Popen[bytes]:
    return subprocess.Popen([sys.executable, "-c", "while True: pass"], stdin=subprocess.DEVNULL)


def certify(name: str, work: Path, seed: int) -> dict[str, object]:
    args = argparse.Namespace(time_out=0, limit=120, mem_limit=1024, base_seed=0)
    row = run_robot(EXPECTATIONS[name], args, work, seed, False)
    try:
        doc = json.loads((work / f"{name}-{seed}" / "report" / "summary.json").read_text())
    except (OSError, ValueError) as exc:
        return {"exit": row.exit, "duration_s": row.wall_s, "fails": [f"no summary ({type(exc).__name__})"],
                "starved": 0, "explained": 0, "first": row.notes[-1] if row.notes else ""}
    cases = doc["cases"]
    fails = [c for c in cases if c["verdict"] in ("FAIL", "ERROR")]
    return {
        "exit": row.exit, "duration_s": float(doc["suite"]["duration_s"]),
        "fails": [c["id"] for c in fails],
        "starved": sum(1 for c in cases if c["verdict"] == "INCONCLUSIVE" and "starved" in c["message"]),
        "explained": sum(1 for c in fails if ROBOT_STARVED in c["message"]),
        "first": f"{fails[0]['id']}: {fails[0]['message'][:200]}" if fails else "",
    }


def one_round(out: Path, n: int) -> dict[str, dict[str, object]]:
    return {name: certify(name, out / f"r{n}", n) for name in ROBOTS}


def table(rounds: list[dict[str, dict[str, object]]]) -> tuple[list[str], int]:
    lines, failing = [], 0
    for name in ROBOTS:
        rows = [r[name] for r in rounds]
        bad = [r for r in rows if r["fails"]]
        failing += len(bad)
        cases = sorted({c for r in bad for c in r["fails"]})  # type: ignore[attr-defined]
        starved = sum(int(r["starved"]) for r in rows)  # type: ignore[call-overload]
        explained = sum(int(r["explained"]) for r in rows)  # type: ignore[call-overload]
        took = [float(r["duration_s"]) for r in rows]  # type: ignore[arg-type]
        first = next((str(r["first"]) for r in bad), "")
        lines.append(f"{name:<12} {len(rows):>4} {len(bad):>9} {starved:>8} {explained:>10} {statistics.median(took):>7.1f} "
                     f"{max(took):>7.1f}  {','.join(cases) or '-'}  {first}")
    return lines, failing


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--rounds", type=int, default=3, help="loaded rounds (each certifies every robot once)")
    parser.add_argument("--hogs", type=int, default=2, help="CPU hog processes during the loaded rounds")
    parser.add_argument("--out", type=Path, help="keep the reports here (default: a temporary directory)")
    args = parser.parse_args(argv)
    print(f"load average before: {' '.join(f'{x:.2f}' for x in os.getloadavg())}  cores: {os.cpu_count()}")
    hogs: list[subprocess.Popen[bytes]] = []
    header = (f"{'robot':<12} {'runs':>4} {'FAIL runs':>9} {'starved':>8} {'explained':>10} {'p50 s':>7} {'max s':>7}"
              "  failed cases  first FAIL")
    try:
        with tempfile.TemporaryDirectory(prefix="bench-certify-loaded-") as tmp:
            out = args.out or Path(tmp)
            quiet = [one_round(out, 0)]
            hogs = [hog() for _ in range(args.hogs)]
            loaded = []
            for n in range(1, args.rounds + 1):
                loaded.append(one_round(out, n))
                print(f"round {n}/{args.rounds}: " + ", ".join(
                    f"{k} {'FAIL ' + ','.join(v['fails']) if v['fails'] else 'clean'} ({float(v['duration_s']):.1f} s)"  # type: ignore[arg-type]
                    for k, v in loaded[-1].items()), flush=True)
    finally:
        for p in hogs:
            p.kill()
            p.wait(10)
    print(f"\nquiet baseline (no hogs):\n{header}")
    print("\n".join(table(quiet)[0]))
    lines, failing = table(loaded)
    print(f"\nloaded: {args.hogs} CPU hogs, {args.rounds} rounds:\n{header}")
    print("\n".join(lines))
    print(f"load average after:  {' '.join(f'{x:.2f}' for x in os.getloadavg())}")
    return 0 if failing == 0 else 1


if __name__ == "__main__":
    sys.exit(main())

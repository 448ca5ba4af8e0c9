"""Timing verdicts on a loaded runner: legal robots and boxes judged while the machine runs well past its cores.

Run on demand: ``python benchmarks/bench_loaded_timing.py [--rounds 20] [--hogs 4] [--out DIR]``.

``--hogs`` CPU hog processes (busy loops) run throughout. Each round runs three suite
processes at once, all against legal implementations:

- ``run --cases T1-01 --cases T2-01 --cases S6-02`` against the bundled reference box;
- the same against ``tests/impls`` box ``trust-header`` (its own process);
- ``certify-robot`` against ``tests/impls`` robot ``canonical`` (T2 rate and jitter, T1 waits).

A T1 or T2 FAIL in any of them is a false alarm (the implementations are legal); an
INCONCLUSIVE that names the starved tester is the honest answer on a starved machine. The
table gives, per kind, the runs, the false T1/T2 FAILs, the starved INCONCLUSIVEs and the
median wall time; before it, one quiet round without hogs is the baseline measured in the
same run. The load average before and after is printed too.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from tests.impls.expectations import EXPECTATIONS  # noqa: E402
from tests.impls.matrix import ROOT, Proc, run_robot, suite_command  # noqa: E402

TIMING = ("T1", "T2")
CASES = ("T1-01", "T2-01", "S6-02")


def hog() -> subprocess.Popen[bytes]:
    return subprocess.Popen([sys.executable, "-c", "while True: pass"], stdin=subprocess.DEVNULL)


def _judge(summary: Path) -> tuple[int, int, str]:
    """(false T1/T2 FAILs, starved INCONCLUSIVEs, the first false alarm) of one report."""
    try:
        cases = json.loads(summary.read_text())["cases"]
    except (OSError, ValueError, KeyError) as exc:
        return 1, 0, f"no summary ({type(exc).__name__})"
    fails = [c for c in cases if c["verdict"] in ("FAIL", "ERROR")
             and set(c.get("judged") or c.get("clauses") or []) & set(TIMING)]
    starved = [c for c in cases if c["verdict"] == "INCONCLUSIVE" and "starved" in (c.get("message") or "")]
    first = f"{fails[0]['id']}: {str(fails[0].get('message'))[:160]}" if fails else ""
    return len(fails), len(starved), first


def run_cases(work: Path, target: str | None) -> dict[str, object]:
    work.mkdir(parents=True, exist_ok=True)
    cmd = suite_command() + ["run", "--quiet", "--capture", "off", "--report-dir", str(work / "report")]
    cmd += [arg for case in CASES for arg in ("--cases", case)] + (["--target", target] if target else [])
    proc = Proc(cmd, work, "suite")
    rc = proc.wait(300)
    fails, starved, first = _judge(work / "report" / "summary.json")
    return {"exit": rc, "wall_s": time.monotonic() - proc.t0, "false": fails, "starved": starved, "first": first}


def certify(work: Path, seed: int) -> dict[str, object]:
    args = argparse.Namespace(time_out=0, limit=120, mem_limit=1024, base_seed=0)
    row = run_robot(EXPECTATIONS["canonical"], args, work, seed, False)
    fails, starved, first = _judge(work / f"canonical-{seed}" / "report" / "summary.json")
    return {"exit": row.exit, "wall_s": row.wall_s, "false": fails, "starved": starved, "first": first}


def one_round(out: Path, n: int, box_target: str) -> dict[str, dict[str, object]]:
    with ThreadPoolExecutor(3) as pool:
        jobs = {"run/bundled": pool.submit(run_cases, out / f"r{n}-bundled", None),
                "run/trust-header": pool.submit(run_cases, out / f"r{n}-box", box_target),
                "certify/canonical": pool.submit(certify, out / f"r{n}-robot", n)}
        return {k: f.result() for k, f in jobs.items()}


def table(rounds: list[dict[str, dict[str, object]]]) -> tuple[list[str], int]:
    lines, false_total = [], 0
    for kind in rounds[0]:
        rows = [r[kind] for r in rounds]
        false = sum(int(r["false"]) for r in rows)  # type: ignore[call-overload]
        false_total += false
        starved = sum(int(r["starved"]) for r in rows)  # type: ignore[call-overload]
        wall = statistics.median(float(r["wall_s"]) for r in rows)  # type: ignore[arg-type]
        first = next((str(r["first"]) for r in rows if r["first"]), "")
        lines.append(f"{kind:<20} {len(rows):>4} {false:>11} {starved:>9} {wall:>8.1f}  {first}")
    return lines, false_total


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--rounds", type=int, default=20, help="loaded rounds (each: three suites at once)")
    parser.add_argument("--hogs", type=int, default=4, help="CPU hog processes during the loaded rounds")
    parser.add_argument("--out", type=Path, help="keep the reports here (default: a temporary directory)")
    args = parser.parse_args(argv)
    print(f"load average before: {' '.join(f'{x:.2f}' for x in os.getloadavg())}  cores: {os.cpu_count()}")
    box = subprocess.Popen([sys.executable, "-m", "tests.impls.box", "trust-header", "--port", "0"], cwd=ROOT,
                           stdout=subprocess.PIPE, text=True)
    hogs: list[subprocess.Popen[bytes]] = []
    try:
        line = box.stdout.readline() if box.stdout is not None else ""
        target = line.split()[2]
        with tempfile.TemporaryDirectory(prefix="bench-loaded-") as tmp:
            out = args.out or Path(tmp)
            quiet = [one_round(out, 0, target)]
            hogs = [hog() for _ in range(args.hogs)]
            loaded = []
            for n in range(1, args.rounds + 1):
                loaded.append(one_round(out, n, target))
                print(f"round {n}/{args.rounds}: " + ", ".join(
                    f"{k} false {v['false']} starved {v['starved']}" for k, v in loaded[-1].items()), flush=True)
        header = f"{'kind':<20} {'runs':>4} {'false T1/T2':>11} {'starved':>9} {'p50 s':>8}  first false alarm"
        print(f"\nquiet baseline (no hogs):\n{header}")
        print("\n".join(table(quiet)[0]))
        lines, false_total = table(loaded)
        print(f"\nloaded: {args.hogs} CPU hogs + 3 suites at once, {args.rounds} rounds:\n{header}")
        print("\n".join(lines))
    finally:
        for p in hogs:
            p.kill()
        box.terminate()
        box.wait(10)
    print(f"load average after:  {' '.join(f'{x:.2f}' for x in os.getloadavg())}")
    return 0 if false_total == 0 else 1


if __name__ == "__main__":
    sys.exit(main())

"""Root-cause benchmark: is the headline (the first root cause) the mechanism each box really has?

``python benchmarks/bench_rootcause.py [--only NAME ...] [--base-seed B] [--jobs 1] [--out DIR]``

For every systematic defect of ``tests/impls/systematic.py`` (each on a random legal base drawn
from ``--base-seed`` and its name), starts the box in this process, runs the whole suite against
it (``isight-conformance run``, its own process) and reads ``summary.json``: the first root cause's
confirmed mechanism against the one the defect declares. Prints per box **right** (confirmed, the
declared mechanism), **wrong** (confirmed, another mechanism: the case to never see),
**unconfirmed** (no experiment confirmed one) or **missed** (no root cause at all), with the
diagnose phase's time, then the totals against the goal: >= 95 % right, 0 wrong, <= 20 s.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import threading
import time
import zlib
from concurrent.futures import ThreadPoolExecutor
from dataclasses import asdict, dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from tests.impls.box import describe  # noqa: E402
from tests.impls.boxcore import ThreadBox  # noqa: E402 - the project root first
from tests.impls.policy import random_choices  # noqa: E402
from tests.impls.systematic import SYSTEMATIC, fixed_knobs  # noqa: E402

GOAL_RIGHT = 0.95
GOAL_PHASE_S = 20.0


@dataclass
class Row:
    name: str
    expected: str
    base_seed: int
    verdict: str = ""  # right | wrong | unconfirmed | missed | no result
    got: str = ""  # the headline's mechanism
    title: str = ""
    phase_s: float = 0.0
    run_s: float = 0.0
    exit: int | None = None
    knobs: str = ""


def _quiet(args: threading.ExceptHookArgs) -> None:
    """A box's writer thread meets a peer that went away: not worth a traceback in the table."""
    if args.exc_type is not None and issubclass(args.exc_type, (BrokenPipeError, ConnectionResetError)):
        return
    threading.__excepthook__(args)


def base_seed(name: str, base: int) -> int:
    return (zlib.crc32(name.encode()) + base) % 1_000_000


def run_one(name: str, args: argparse.Namespace, out: Path) -> Row:
    seed = base_seed(name, args.base_seed)
    choices = random_choices(seed, fixed=fixed_knobs(name)).with_defect(name)
    row = Row(name, SYSTEMATIC[name].mechanism, seed, knobs=describe(choices))
    work = out / name
    work.mkdir(parents=True, exist_ok=True)
    with ThreadBox(choices) as box:
        cmd = [sys.executable, "-m", "conformance", "run", "--target", f"127.0.0.1:{box.port}", "--quiet",
               "--capture", "off", "--report-dir", str(work / "report"), "--time-out", str(args.time_out),
               *choices.suite_args()]
        t0 = time.monotonic()
        try:
            done = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, timeout=args.limit,
                                  env={**os.environ, "PYTHONPATH": str(ROOT)})
            row.exit = done.returncode
            (work / "suite.stdout").write_text(done.stdout + done.stderr)
        except subprocess.TimeoutExpired:
            row.verdict = "no result"
        row.run_s = round(time.monotonic() - t0, 1)
    try:
        doc = json.loads((work / "report" / "summary.json").read_text())
    except (OSError, ValueError):
        row.verdict = row.verdict or "no result"
        return row
    causes = doc.get("root_causes", [])
    if not causes:
        row.verdict = "missed"
        return row
    first = causes[0]
    diagnosis = first.get("diagnosis") or {}
    row.title = first.get("title", "")
    row.got = str(diagnosis.get("mechanism") or first.get("kind", ""))
    row.phase_s = float(diagnosis.get("phase_s", 0.0))
    if not first.get("confirmed"):
        row.verdict = "unconfirmed"
    else:
        row.verdict = "right" if row.got == row.expected else "wrong"
    return row


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--only", nargs="+", metavar="NAME", help="only these defects")
    parser.add_argument("--base-seed", type=int, default=1, help="random legal bases drawn from B and the name")
    parser.add_argument("--jobs", type=int, default=1, help="boxes run at once (default 1)")
    parser.add_argument("--limit", type=float, default=600, help="hard bound per suite run, seconds")
    parser.add_argument("--time-out", type=int, default=2000, metavar="MS",
                        help="the suite's time_out (default 2000, as tests/e2e runs broken boxes: a box that leaves "
                             "requests unanswered costs a time_out in each of ~60 cases)")
    parser.add_argument("--out", type=Path, default=None, help="where reports go (default reports/bench-rootcause-*)")
    args = parser.parse_args(argv)
    threading.excepthook = _quiet
    names = args.only or list(SYSTEMATIC)
    unknown = [n for n in names if n not in SYSTEMATIC]
    if unknown:
        print(f"error: unknown defect(s): {', '.join(unknown)}", file=sys.stderr)
        return 2
    out = args.out or ROOT / "reports" / time.strftime("bench-rootcause-%Y%m%d-%H%M%S")
    out.mkdir(parents=True, exist_ok=True)
    t0 = time.monotonic()

    def one(name: str) -> Row:
        row = run_one(name, args, out)
        print(f"{row.name:<24} {row.verdict:<12} expected {row.expected:<16} got {row.got:<16} "
              f"diagnose {row.phase_s:5.1f} s  run {row.run_s:6.1f} s  | {row.title[:110]}", flush=True)
        return row

    with ThreadPoolExecutor(max_workers=args.jobs) as pool:
        rows = list(pool.map(one, names))
    (out / "bench-rootcause.json").write_text(json.dumps([asdict(r) for r in rows], indent=1) + "\n")
    counts = {v: sum(r.verdict == v for r in rows) for v in ("right", "wrong", "unconfirmed", "missed", "no result")}
    phases = sorted(r.phase_s for r in rows)
    right = counts["right"] / len(rows)
    print(f"\n{len(rows)} boxes: " + ", ".join(f"{n} {v}" for v, n in counts.items()))
    print(f"right {right:.0%} (goal >= {GOAL_RIGHT:.0%}); wrong-but-confident {counts['wrong']} (goal 0); diagnose "
          f"phase median {phases[len(phases) // 2]:.1f} s, max {phases[-1]:.1f} s (goal <= {GOAL_PHASE_S:.0f} s); "
          f"{time.monotonic() - t0:.0f} s in all at --jobs {args.jobs}; reports: {out}")
    ok = right >= GOAL_RIGHT and counts["wrong"] == 0 and phases[-1] <= GOAL_PHASE_S
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())

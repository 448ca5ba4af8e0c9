"""Verdict truth at speed: wall time, peak memory and first root cause for the issue-9 endpoints.

Run on demand: ``python benchmarks/bench_verdicts.py [--only NAME ...] [--out DIR]``.

Each endpoint is one full ``isight-conformance run`` in a child process, watched for wall
time and peak resident memory (VmHWM) by :class:`tests.impls.matrix.Proc`:

- ``reference``: no ``--target``, so the bundled reference box (the embedded default);
- the independent boxes of ``tests/impls`` that once made the suite hang, blow up or
  blame the wrong clause: ``dead``, ``swapped-version``, ``late-cycle-on``,
  ``flood-random``, ``flood-headers``, ``leaky``, and the boxes that go quiet (issue 17:
  bounded time for every box that answers at all): ``no-resync`` (silent after garbage,
  R6), ``drops-coalesced`` (answers only the first frame of a read, R4),
  ``one-at-a-time`` (S4), and the boxes of issue 25 (every box judged in bounded time,
  whatever it does): ``sticky-error`` (after an error every answer repeats its code),
  ``drops-frames`` (every 7th answer never written), ``answers-some-actions`` (Tolerance
  and RegisterPose never answered), ``quiet-after-n`` (silent after 150 answers),
  ``short-send-drops`` (drops what a short non-blocking send left, S6), ``latency-grows``
  (T2 backlog) and the legal ``late-inside-timeout`` (every answer 100 ms late);
- every other conforming box of ``tests/impls`` (``resync-fine`` ... ``nan-1001``: each a different
  legal reading), for the goal "a conforming box in <= 30 s";
- issue 36 (bounds on time at the default time_out): ``drops-rest-of-read`` (handles one whole frame per
  read and discards the rest, R4), ``split-header-lost`` (a read shorter than a header at a frame's start is
  dropped, R3), the legal ``slow-pieces`` (20 ms late, two pieces with Nagle) and ``slow-cycle-on``
  (CycleOn after 0.6 time_out); and the Node.js boxes written outside this project (``node:NAME``,
  ``tests/impls/node``: the legal ``legal-a`` ... ``legal-f`` and the tuning defects ``d19`` (R4) and
  ``d02`` (R3)), never the held-out ones.

Each box is started by ``python -m tests.impls.box NAME``, exactly as the matrix does; a Node.js box by
``node tests/impls/node/box.js NAME --port 0`` (its first line names its ports and the flags it needs).

``--serial-too`` runs each endpoint a second time with ``--lanes 1`` (one case at a time) and
prints it beside the default run (``--lanes auto``: lanes for a slow box that serves several
connections), the baseline in the same run. Peak RSS is the suite's main process (lane
workers are separate processes).

It prints one line per endpoint: exit code, wall time, peak RSS, the judgement against
``tests/impls/expectations.py`` and the first root cause the run reported. The load
average before and after is printed too: the figures measure the machine as much as the
suite. The last lines give the goals of issue 25: the longest run, the median over the
broken boxes and the longest conforming run (reference and late-inside-timeout).
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import statistics
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from tests.impls.expectations import EXPECTATIONS  # noqa: E402
from tests.impls.matrix import Proc, run_box, suite_command, target_args  # noqa: E402

ENDPOINTS = ["reference", "no-resync", "drops-coalesced", "one-at-a-time", "dead", "swapped-version",
             "late-cycle-on", "flood-random", "flood-headers", "leaky",
             # issue 25: bounded time whatever the box does
             "sticky-error", "drops-frames", "answers-some-actions", "quiet-after-n", "short-send-drops",
             "latency-grows", "late-inside-timeout",
             # the other conforming boxes of tests/impls: issue 25's "conforming box <= 30 s" for each legal reading
             "resync-fine", "skip-header", "trust-header", "close-on-garbage", "byte-by-byte", "strict-cycle",
             "strict-cycle-box", "unknown-error", "nan-1001",
             # issue 36: the kinds of box that took longest, and the Node.js boxes written outside this project
             "drops-rest-of-read", "split-header-lost", "slow-pieces", "slow-cycle-on",
             "node:d19", "node:d02", *(f"node:legal-{c}" for c in "abcdef")]
#: the conforming endpoints (the rest are broken)
CONFORMING = ("reference", *(n for n in ENDPOINTS if n in EXPECTATIONS and EXPECTATIONS[n].conforming),
              *(n for n in ENDPOINTS if n.startswith("node:legal-")))
#: the legal boxes that answer late: their bound is 30 s + 600 x their answer latency (seconds)
LATENCY_S = {"late-inside-timeout": 0.1, "slow-pieces": 0.02, "node:legal-b": 0.01, "node:legal-c": 0.06,
             "node:legal-d": 0.002, "node:legal-e": 0.02}
#: ... and those whose CycleOn alone is slow (1.5 s, 3 s): no latency bound fits them, only "every box <= 120 s"
SLOW_CYCLE_ON = ("slow-cycle-on", "node:legal-e")
NODE_BOX = Path(__file__).resolve().parents[1] / "tests" / "impls" / "node" / "box.js"


def run_reference(out: Path, limit: float, extra: tuple[str, ...] = ()) -> dict[str, object]:
    work = out / ("reference" + "-".join(("",) + extra))
    work.mkdir(parents=True, exist_ok=True)
    suite = Proc(suite_command() + ["run", "--quiet", "--report-dir", str(work / "report"),
                                    "--pcap-dir", str(work / "pcaps"), *extra], work, "suite")
    rc = suite.wait(limit)
    wall = time.monotonic() - suite.t0
    try:
        doc = json.loads((work / "report" / "summary.json").read_text())
        totals = {k: v for k, v in doc.get("totals", {}).items() if v}
        bad = sum(totals.get(k, 0) for k in ("FAIL", "ERROR", "NON-STRICT"))
        judgement = "ok" if rc == 0 and not bad else f"NOT CLEAN ({totals})"
        first = (doc.get("root_causes") or [{}])[0]
    except (OSError, ValueError) as exc:
        judgement, first = f"no summary.json ({type(exc).__name__})", {}
    return {"name": "reference", "exit": rc if rc is not None else suite.killed, "wall_s": wall,
            "peak_rss_mb": suite.peak_kb / 1024, "judgement": judgement, "root_cause": _rc_text(first)}


def _rc_text(rc: dict[str, object]) -> str:
    if not rc:
        return "-"
    clauses = ",".join(rc.get("clauses", []))  # type: ignore[arg-type]
    return f"{rc.get('id')} [{clauses}] {rc.get('level', '')}: {str(rc.get('title', ''))[:60]}"


def run_impl(name: str, out: Path, limit: float, extra: tuple[str, ...] = ()) -> dict[str, object]:
    args = argparse.Namespace(time_out=0, limit=limit, mem_limit=4096)
    exp = EXPECTATIONS[name]
    row = run_box(replace(exp, suite_args=(*exp.suite_args, *extra)), args, out / "-".join((name,) + extra), 0, False)
    return {"name": name, "exit": row.exit, "wall_s": row.wall_s, "peak_rss_mb": row.peak_rss_mb,
            "judgement": row.judgement, "root_cause": (row.root_causes or ["-"])[0][:90]}


def run_node(name: str, out: Path, limit: float, extra: tuple[str, ...] = ()) -> dict[str, object]:
    """A Node.js box of ``tests/impls/node`` (``node:NAME``): legal ones must come out clean, a tuning defect
    with a FAIL or NON-STRICT (its first root cause is printed)."""
    box_name = name.removeprefix("node:")
    work = out / "-".join((name.replace(":", "-"),) + extra)
    work.mkdir(parents=True, exist_ok=True)
    if shutil.which("node") is None:
        return {"name": name, "exit": None, "wall_s": 0.0, "peak_rss_mb": 0.0,
                "judgement": "not run: node (Node.js 20) is not installed", "root_cause": "-"}
    box = Proc(["node", str(NODE_BOX), box_name, "--port", "0"], work, "box")
    line = box.first_line(20)
    if line is None or not line.startswith("listening tcp "):
        box.stop()
        return {"name": name, "exit": None, "wall_s": 0.0, "peak_rss_mb": 0.0, "judgement": "box did not start",
                "root_cause": "-"}
    suite = Proc(suite_command() + ["run", *target_args(line), "--quiet", "--report-dir", str(work / "report"),
                                    "--pcap-dir", str(work / "pcaps"), *extra], work, "suite")
    rc = suite.wait(limit)
    wall = time.monotonic() - suite.t0
    box.stop()
    try:
        doc = json.loads((work / "report" / "summary.json").read_text())
        totals = {k: v for k, v in doc.get("totals", {}).items() if v}
        bad = sum(totals.get(k, 0) for k in ("FAIL", "ERROR", "NON-STRICT"))
        if box_name.startswith("legal-"):
            judgement = "ok" if rc == 0 and not bad else f"NOT CLEAN ({totals})"
        else:
            judgement = "ok" if bad else "MISSED (no FAIL)"
        first = (doc.get("root_causes") or [{}])[0]
    except (OSError, ValueError) as exc:
        judgement, first = f"no summary.json ({type(exc).__name__})", {}
    return {"name": name, "exit": rc if rc is not None else suite.killed, "wall_s": wall,
            "peak_rss_mb": suite.peak_kb / 1024, "judgement": judgement, "root_cause": _rc_text(first)}


def goals(walls: dict[str, float]) -> None:
    """Issue 25's goals beside the figures: max <= 120 s, median broken <= 60 s, conforming <= 30 s."""
    broken = sorted(w for n, w in walls.items() if n not in CONFORMING)
    conforming = [w for n, w in walls.items() if n in CONFORMING]
    if walls:
        name = max(walls, key=walls.__getitem__)
        print(f"max {walls[name]:.1f} s ({name}; goal <= 120 s)")
    if broken:
        print(f"median broken {statistics.median(broken):.1f} s over {len(broken)} boxes (goal <= 60 s)")
    if conforming:
        print(f"conforming max {max(conforming):.1f} s (goal <= 30 s)")
        prompt = [w for n, w in walls.items() if n in CONFORMING and n not in LATENCY_S and n not in SLOW_CYCLE_ON]
        if prompt:
            print(f"conforming max of the boxes that answer at once {max(prompt):.1f} s (goal <= 30 s)")
        for n, d in LATENCY_S.items():
            if n in walls:
                print(f"{n} (answers {d * 1000:.0f} ms late) {walls[n]:.1f} s (goal <= {30 + 600 * d:.0f} s"
                      f"{', more for its slow CycleOns' if n in SLOW_CYCLE_ON else ''})")
        for n in SLOW_CYCLE_ON:
            if n in walls and n not in LATENCY_S:
                print(f"{n} (CycleOn slow) {walls[n]:.1f} s (goal <= 120 s, every box)")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--only", nargs="+", choices=ENDPOINTS, metavar="NAME", help="only these endpoints")
    parser.add_argument("--limit", type=float, default=900, metavar="S", help="hard bound per run (s)")
    parser.add_argument("--out", type=Path, help="keep the reports here (default: a temporary directory)")
    parser.add_argument("--serial-too", action="store_true",
                        help="also run each endpoint with --lanes 1 (one case at a time), printed beside the default "
                             "(--lanes auto) as its baseline")
    args = parser.parse_args(argv)
    names = args.only or ENDPOINTS
    print(f"load average before: {' '.join(f'{x:.2f}' for x in os.getloadavg())}  cores: {os.cpu_count()}")
    print(f"{'endpoint':<20} {'exit':>4} {'wall s':>7} {'peak MB':>8}  {'judgement':<24} first root cause")
    with tempfile.TemporaryDirectory(prefix="bench-verdicts-") as tmp:
        out = args.out or Path(tmp)
        out.mkdir(parents=True, exist_ok=True)
        ok = True
        walls: dict[str, float] = {}
        for name in names:
            for extra in [(), ("--lanes", "1")] if args.serial_too else [()]:
                run = run_reference if name == "reference" else run_node if name.startswith("node:") else run_impl
                r = run(out, args.limit, extra) if name == "reference" else run(name, out, args.limit, extra)
                ok = ok and r["judgement"] == "ok"
                label = name + (" (lanes 1)" if extra else "")
                if not extra:
                    walls[name] = float(r["wall_s"])  # type: ignore[arg-type]
                print(f"{label:<20} {r['exit']!s:>4} {r['wall_s']:>7.1f} {r['peak_rss_mb']:>8.1f}  "
                      f"{r['judgement']!s:<24} {r['root_cause']}", flush=True)
    goals(walls)
    print(f"load average after:  {' '.join(f'{x:.2f}' for x in os.getloadavg())}")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())

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
  legal reading), for the goal "a conforming box in <= 30 s".

Each box is started by ``python -m tests.impls.box NAME``, exactly as the matrix does.

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
import statistics
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from tests.impls.expectations import EXPECTATIONS  # noqa: E402
from tests.impls.matrix import Proc, run_box, suite_command  # noqa: E402

ENDPOINTS = ["reference", "no-resync", "drops-coalesced", "one-at-a-time", "dead", "swapped-version",
             "late-cycle-on", "flood-random", "flood-headers", "leaky",
             # issue 25: bounded time whatever the box does
             "sticky-error", "drops-frames", "answers-some-actions", "quiet-after-n", "short-send-drops",
             "latency-grows", "late-inside-timeout",
             # the other conforming boxes of tests/impls: issue 25's "conforming box <= 30 s" for each legal reading
             "resync-fine", "skip-header", "trust-header", "close-on-garbage", "byte-by-byte", "strict-cycle",
             "strict-cycle-box", "unknown-error", "nan-1001"]
#: the conforming endpoints (the rest are broken)
CONFORMING = ("reference", *(n for n in ENDPOINTS if n in EXPECTATIONS and EXPECTATIONS[n].conforming))


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
        prompt = [w for n, w in walls.items() if n in CONFORMING and n != "late-inside-timeout"]
        if prompt:
            print(f"conforming max without the box that answers 100 ms late {max(prompt):.1f} s (goal <= 30 s)")


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
                r = run_reference(out, args.limit, extra) if name == "reference" else run_impl(name, out, args.limit,
                                                                                              extra)
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

"""Held-out benchmark: does the first root cause of a box nobody here wrote state the mechanism its author planted?

``python benchmarks/bench_heldout.py [--set tuning|heldout] [--only NAME ...] [--jobs 2] [--no-legal]
[--boxes DIR] [--out DIR]``

The boxes are programs in other languages: Node.js (``tests/impls/node/box.js NAME --port 0``) or Perl
(``tests/impls/perl/box.pl NAME --port 0``, with ``--boxes tests/impls/perl``); a box's first stdout line is
``listening tcp 127.0.0.1:PORT [udp 127.0.0.1:UPORT] [args FLAG ...]``), written from docs/PROTOCOL.md and a
list of mechanism classes by someone who never read ``conformance/diagnose/``. A set's ``CATALOGUE.json``
names each box's class, clauses, mechanism, keywords and trigger. For every box the bench starts it
(bounded), runs ``isight-conformance run --quiet --report-dir DIR`` against it (with ``--udp-target`` and
the flags the box asks for), reads ``summary.json`` and prints:

* the first root cause's title, and whether it **states the mechanism**: every keyword of the catalogue
  appears in it (case-insensitive) and it is not ``unconfirmed:``;
* its **orphan FAILs**: FAIL cases no root cause lists;
* the run's time.

The legal boxes (``legal/CATALOGUE.json``, or box.js's own legal boxes) run too: any FAIL or NON-STRICT on
them is a **false finding**. Totals against the goals: >= 90 % stated, 0 orphans, 0 false findings.
The held-out set is scored once, at the end, by whoever did not tune on it.
"""

from __future__ import annotations

import argparse
import json
import os
import select
import subprocess
import sys
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
GOAL_STATED = 0.90
START_S = 10.0  # bound on a box's start (its "listening" line)
LEGAL_BOXES = ("legal-a", "legal-b", "legal-c", "legal-d", "legal-e", "legal-f")


@dataclass
class Row:
    name: str
    kind: str  # "defect" | "legal"
    keywords: list[str] = field(default_factory=list)
    title: str = ""
    stated: bool = False
    orphans: list[str] = field(default_factory=list)
    findings: list[str] = field(default_factory=list)  # legal boxes: FAIL / NON-STRICT cases
    fails: int = 0
    run_s: float = 0.0
    exit: int | None = None
    error: str = ""


def catalogue(path: Path) -> list[dict[str, Any]]:
    """The entries of a CATALOGUE.json (a list, or an object holding one under "boxes", or name -> entry)."""
    doc = json.loads(path.read_text())
    if isinstance(doc, dict) and isinstance(doc.get("boxes"), list):
        doc = doc["boxes"]
    if isinstance(doc, dict):
        doc = [{"name": k, **v} for k, v in doc.items() if isinstance(v, dict)]
    return [e for e in doc if isinstance(e, dict) and e.get("name")]


def states_mechanism(title: str, keywords: list[str]) -> bool:
    low = title.lower()
    return bool(title) and not low.startswith("unconfirmed") and all(k.lower() in low for k in keywords)


def orphans(doc: dict[str, Any]) -> tuple[list[str], list[str]]:
    """(every FAIL case id, the FAIL cases no root cause lists)."""
    cases = doc.get("cases", [])
    fails = [c["id"] for c in cases if str(c.get("verdict", "")).upper() == "FAIL"]
    listed = {i for rc in doc.get("root_causes", []) for i in rc.get("cases", [])}
    return fails, [i for i in fails if i not in listed]


#: a box program's interpreter, by the program's name in the boxes' directory
PROGRAMS = (("box.js", "node"), ("box.pl", "perl"))


def box_program(boxes: Path) -> list[str] | None:
    """The command that runs the directory's box program (``node box.js`` or ``perl box.pl``), or None."""
    for name, interpreter in PROGRAMS:
        if (boxes / name).is_file():
            return [interpreter, str(boxes / name)]
    return None


def start_box(program: list[str], name: str) -> tuple[subprocess.Popen[str], str]:
    """The box's process and its "listening" line (raises RuntimeError when it does not start in START_S)."""
    proc = subprocess.Popen([*program, name, "--port", "0"], stdout=subprocess.PIPE,
                            stderr=subprocess.DEVNULL, text=True)
    assert proc.stdout is not None
    ready, _, _ = select.select([proc.stdout], [], [], START_S)
    line = proc.stdout.readline().strip() if ready else ""
    if not line.startswith("listening"):
        stop_box(proc)
        raise RuntimeError(f"box {name} did not start: {line or 'no listening line'}")
    return proc, line


def stop_box(proc: subprocess.Popen[str]) -> None:
    proc.terminate()
    try:
        proc.wait(5)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.wait(5)


def suite_args(line: str) -> list[str]:
    """``--target``, ``--udp-target`` and the flags from a box's listening line."""
    words = line.split()
    out: list[str] = []
    if "tcp" in words:
        out += ["--target", words[words.index("tcp") + 1]]
    if "udp" in words:
        out += ["--udp-target", words[words.index("udp") + 1]]
    if "args" in words:
        out += words[words.index("args") + 1:]
    return out


def run_one(entry: dict[str, Any], kind: str, args: argparse.Namespace, out: Path) -> Row:
    name = str(entry["name"])
    keywords = [str(k) for k in entry.get("keywords", [])]
    row = Row(name, kind, keywords)
    work = out / name
    work.mkdir(parents=True, exist_ok=True)
    t0 = time.monotonic()
    try:
        proc, line = start_box(args.program, name)
    except (RuntimeError, OSError) as exc:
        row.error = str(exc)
        return row
    try:
        cmd = [sys.executable, "-m", "conformance", "run", *suite_args(line), "--quiet", "--capture", "off",
               "--report-dir", str(work / "report"), "--time-out", str(args.time_out)]
        try:
            done = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, timeout=args.limit,
                                  env={**os.environ, "PYTHONPATH": str(ROOT)})
            row.exit = done.returncode
            (work / "suite.stdout").write_text(done.stdout + done.stderr)
        except subprocess.TimeoutExpired:
            row.error = f"the run took more than {args.limit:.0f} s"
    finally:
        stop_box(proc)
        row.run_s = round(time.monotonic() - t0, 1)
    try:
        doc = json.loads((work / "report" / "summary.json").read_text())
    except (OSError, ValueError):
        row.error = row.error or "no summary.json"
        return row
    causes = doc.get("root_causes", [])
    row.title = str(causes[0].get("title", "")) if causes else ""
    row.stated = states_mechanism(row.title, keywords)
    fails, row.orphans = orphans(doc)
    row.fails = len(fails)
    if kind == "legal":
        row.findings = [f"{c['id']} {c.get('verdict')}" for c in doc.get("cases", [])
                        if str(c.get("verdict", "")).upper().replace("_", "-") in ("FAIL", "NON-STRICT")]
    return row


def _print(row: Row) -> None:
    if row.kind == "legal":
        what = "clean" if not row.findings and not row.error else f"FALSE FINDINGS {', '.join(row.findings)[:160]}"
        print(f"{row.name:<10} legal   {what} {row.error}  run {row.run_s:5.1f} s", flush=True)
        return
    mark = "STATED " if row.stated else "generic"
    print(f"{row.name:<10} {mark} orphans {len(row.orphans)}/{row.fails}  run {row.run_s:5.1f} s  "
          f"{row.error}| {row.title[:150]}  [keywords: {', '.join(row.keywords)}]", flush=True)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--set", choices=("tuning", "heldout"), default="tuning", help="which half (default tuning)")
    parser.add_argument("--only", nargs="+", metavar="NAME", help="only these boxes")
    parser.add_argument("--jobs", type=int, default=1, help="boxes run at once (default 1, at most 2 here)")
    parser.add_argument("--no-legal", action="store_true", help="skip the legal boxes")
    parser.add_argument("--boxes", type=Path, default=ROOT / "tests" / "impls" / "node",
                        help="the directory of box.js or box.pl and the sets (default tests/impls/node)")
    parser.add_argument("--time-out", type=int, default=3000, metavar="MS", help="the suite's time_out (default 3000)")
    parser.add_argument("--limit", type=float, default=600, help="hard bound per suite run, seconds")
    parser.add_argument("--out", type=Path, default=None, help="where reports go (default reports/bench-heldout-*)")
    args = parser.parse_args(argv)
    cat = args.boxes / args.set / "CATALOGUE.json"
    args.program = box_program(args.boxes)
    if args.program is None or not cat.is_file():
        print(f"error: no box.js or box.pl in {args.boxes}, or no {cat}", file=sys.stderr)
        return 2
    try:
        entries = catalogue(cat)
    except (OSError, ValueError) as exc:
        print(f"error: {cat}: {exc}", file=sys.stderr)
        return 2
    legal_cat = args.boxes / "legal" / "CATALOGUE.json"
    legal = [] if args.no_legal else (catalogue(legal_cat) if legal_cat.is_file() else
                                      [{"name": n} for n in LEGAL_BOXES])
    if args.only:
        unknown = set(args.only) - {str(e["name"]) for e in entries + legal}
        if unknown:
            print(f"error: unknown box(es): {', '.join(sorted(unknown))}", file=sys.stderr)
            return 2
        entries = [e for e in entries if e["name"] in args.only]
        legal = [e for e in legal if e["name"] in args.only]
    out = args.out or ROOT / "reports" / time.strftime(f"bench-heldout-{args.set}-%Y%m%d-%H%M%S")
    out.mkdir(parents=True, exist_ok=True)
    t0 = time.monotonic()
    jobs = [(e, "defect") for e in entries] + [(e, "legal") for e in legal]

    def one(job: tuple[dict[str, Any], str]) -> Row:
        row = run_one(job[0], job[1], args, out)
        _print(row)
        return row

    with ThreadPoolExecutor(max_workers=max(1, args.jobs)) as pool:
        rows = list(pool.map(one, jobs))
    (out / "bench-heldout.json").write_text(json.dumps([asdict(r) for r in rows], indent=1) + "\n")
    defects = [r for r in rows if r.kind == "defect"]
    legals = [r for r in rows if r.kind == "legal"]
    stated = sum(r.stated for r in defects)
    orphan_n = sum(len(r.orphans) for r in defects + legals)
    false_n = sum(len(r.findings) for r in legals)
    errors = sum(bool(r.error) for r in rows)
    share = stated / len(defects) if defects else 0.0
    print(f"\n{args.set}: {len(defects)} defect boxes, {stated} state the mechanism ({share:.0%}, goal >= "
          f"{GOAL_STATED:.0%}); orphan FAILs {orphan_n} (goal 0); {len(legals)} legal boxes, false findings "
          f"{false_n} (goal 0); {errors} box(es) without a result; {time.monotonic() - t0:.0f} s in all at --jobs "
          f"{args.jobs}; reports: {out}")
    return 0 if share >= GOAL_STATED and orphan_n == 0 and false_n == 0 and not errors else 1


if __name__ == "__main__":
    sys.exit(main())

"""Run the conformance suite against every independent implementation and tabulate the verdicts.

``python -m tests.impls.matrix [--only NAME ...] [--seeds N] [--time-out MS] [--jobs 1] [--base-seed B]``
``python -m tests.impls.matrix --sample N --seed S [--jobs J]``

``--sample`` runs N random legal combinations of the box's knobs instead (drawn from
``--seed``, reproducible: combination i is ``python -m tests.impls.box random --seed``
its own seed, shown in the table), each against the full suite with the fuzz cases
under that seed; every one must come out clean. Broken boxes sit on a random legal base
drawn from ``--base-seed`` and their name (0: the documented base).

For each box: start ``python -m tests.impls.box NAME --port 0`` (its own process), then
``isight-conformance run --target 127.0.0.1:PORT --quiet --report-dir DIR --pcap-dir DIR``
(plus ``--udp-target``, ``--stream-target`` and the profile flags the box's first line asks for).
For each robot: start ``isight-conformance certify-robot --listen 127.0.0.1:0``, then
``python -m tests.impls.robot NAME --target`` the printed port. Every process has a hard
wall-clock bound and the suite a resident-memory cap (both killed and reported beyond
them). One row per run: name, conforming/broken, expected clause, exit code, wall time,
totals, the first FAIL/NON-STRICT cases, ``root_causes`` when summary.json has them, the
suite's peak RSS and the judgement against :mod:`.expectations`. The table also goes to
``OUT/matrix.md`` and ``OUT/matrix.json``.
"""

from __future__ import annotations

import argparse
import json
import os
import random
import signal
import subprocess
import sys
import time
import zlib
from concurrent.futures import ThreadPoolExecutor
from dataclasses import asdict, dataclass, field
from pathlib import Path

from .expectations import EXPECTATIONS, RANDOM, Expectation, expectation, judge

ROOT = Path(__file__).resolve().parents[2]
SHORT = {"FAIL": "FAIL", "ERROR": "ERR", "NON-STRICT": "NS", "INCONCLUSIVE": "INC", "INFORMATIONAL": "INFO",
         "SKIP": "SKIP", "PASS": "PASS"}


@dataclass
class Row:
    name: str
    role: str
    kind: str
    expected: str
    seed: int = 0
    exit: int | None = None
    wall_s: float = 0.0
    totals: dict[str, int] = field(default_factory=dict)
    first: list[str] = field(default_factory=list)  # "ID VERDICT [clauses]"
    root_causes: list[str] | None = None  # None: summary.json has no "root_causes" key
    peak_rss_mb: float = 0.0
    judgement: str = ""
    notes: list[str] = field(default_factory=list)
    box_seed: int | None = None  # random: the combination; broken: its random base (None: the documented one)
    knobs: str = ""  # the box's knobs that differ from the defaults


def suite_command() -> list[str]:
    """The suite of this checkout: ``python -m conformance`` run with the checkout as its working directory
    (an installed ``isight-conformance`` script imports whichever checkout was installed, not this one)."""
    return [sys.executable, "-m", "conformance"]


class Proc:
    """A subprocess in its own process group, stdout/stderr to files, watched for time and memory."""

    def __init__(self, cmd: list[str], out: Path, name: str) -> None:
        self.cmd = cmd
        self.stdout_path, self.stderr_path = out / f"{name}.stdout", out / f"{name}.stderr"
        with self.stdout_path.open("wb") as so, self.stderr_path.open("wb") as se:
            self.p = subprocess.Popen(cmd, stdout=so, stderr=se, stdin=subprocess.DEVNULL, cwd=ROOT,
                                      start_new_session=True)
        self.t0 = time.monotonic()
        self.rc: int | None = None
        self.peak_kb = 0
        self.killed = ""

    def first_line(self, bound: float) -> str | None:
        deadline = time.monotonic() + bound
        while time.monotonic() < deadline:
            text = self.stdout_path.read_text(errors="replace")
            if "\n" in text:
                return text.split("\n", 1)[0]
            if self.poll() is not None:
                return None
            time.sleep(0.05)
        return None

    def poll(self) -> int | None:
        if self.rc is None:
            try:
                pid, status, usage = os.wait4(self.p.pid, os.WNOHANG)
            except ChildProcessError:
                return self.rc
            if pid:
                self.rc = os.waitstatus_to_exitcode(status)
                self.p.returncode = self.rc
                # ru_maxrss can carry the forking parent's own peak: only a fallback for a very short life
                self.peak_kb = self.peak_kb or usage.ru_maxrss
            else:
                self.peak_kb = max(self.peak_kb, _vm_hwm_kb(self.p.pid))
        return self.rc

    def wait(self, limit: float, mem_mb: float = 0.0) -> int | None:
        """Wait until the process ends, ``limit`` s after its start (then kill), or over ``mem_mb`` of RSS."""
        while self.poll() is None:
            if time.monotonic() - self.t0 > limit:
                self.kill(f"killed after {limit:.0f} s (hard bound)")
            elif mem_mb and _vm_rss_kb(self.p.pid) > mem_mb * 1024:
                self.kill(f"killed at {_vm_rss_kb(self.p.pid) / 1024:.0f} MB RSS (cap {mem_mb:.0f} MB)")
            time.sleep(0.2)
        return None if self.killed else self.rc

    def kill(self, why: str) -> None:
        self.killed = self.killed or why
        try:
            os.killpg(self.p.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
        deadline = time.monotonic() + 10
        while self.poll() is None and time.monotonic() < deadline:
            time.sleep(0.05)

    def stop(self, grace: float = 5.0) -> str:
        """SIGTERM, then SIGKILL after ``grace`` s; a note when it did not stop cleanly."""
        if self.poll() is not None:
            return f"exited early (rc {self.rc})"
        try:
            os.killpg(self.p.pid, signal.SIGTERM)
        except ProcessLookupError:
            return ""
        deadline = time.monotonic() + grace
        while self.poll() is None and time.monotonic() < deadline:
            time.sleep(0.05)
        if self.poll() is None:
            self.kill("SIGKILL")
            return f"did not stop within {grace:.0f} s of SIGTERM (killed)"
        return "" if self.rc in (0, -signal.SIGTERM) else f"stopped with rc {self.rc}"

    def last_line(self) -> str:
        lines = [x for x in self.stderr_path.read_text(errors="replace").splitlines() if x.strip()]
        return lines[-1][:200] if lines else ""


def _proc_status(pid: int, key: str) -> int:
    try:
        for line in Path(f"/proc/{pid}/status").read_text().splitlines():
            if line.startswith(key):
                return int(line.split()[1])
    except (OSError, ValueError, IndexError):
        pass
    return 0


def _vm_hwm_kb(pid: int) -> int:
    return _proc_status(pid, "VmHWM:")


def _vm_rss_kb(pid: int) -> int:
    return _proc_status(pid, "VmRSS:")


def _read_summary(row: Row, report: Path) -> tuple[str, ...]:
    """Fill totals, first cases and root causes from summary.json; the first failing case's clauses."""
    try:
        doc = json.loads((report / "summary.json").read_text())
    except (OSError, ValueError) as exc:
        row.notes.append(f"no summary.json ({type(exc).__name__})")
        return ()
    row.totals = {k: v for k, v in doc.get("totals", {}).items() if v}
    first_clauses: tuple[str, ...] = ()
    for case in doc.get("cases", []):
        if case.get("verdict") in ("FAIL", "ERROR", "NON-STRICT"):
            clauses = tuple(case.get("clauses", ()))
            first_clauses = first_clauses or clauses
            if len(row.first) < 3:
                rc = f" rc={case['root_cause']}" if case.get("root_cause") else ""
                row.first.append(f"{case['id']} {case['verdict']} [{','.join(clauses)}]{rc}")
    if "root_causes" in doc:
        row.root_causes = [f"{r.get('id')} [{','.join(r.get('clauses', []))}] {r.get('level', '')}: "
                           f"{r.get('title', '')} ({len(r.get('cases', []))} cases)" for r in doc["root_causes"]]
        if first_clauses and not doc["root_causes"]:
            row.notes.append("root_causes is empty")
        _judge(row, doc["root_causes"], first_clauses)
    else:
        _judge(row, None, first_clauses)
    return first_clauses


def _judge(row: Row, root_causes: list[dict[str, object]] | None, first_clauses: tuple[str, ...]) -> None:
    row.judgement = judge(expectation(row.name, row.role), row.exit, row.totals, root_causes, first_clauses)


def _new_row(exp: Expectation, seed: int) -> Row:
    expected = "clean" if exp.conforming else f"{'/'.join(exp.clauses)} {exp.level}"
    return Row(exp.name, exp.role, "conforming" if exp.conforming else "broken", expected, seed)


def _suite_flags(args: argparse.Namespace, seed: int, seeded: bool) -> list[str]:
    flags = ["--time-out", str(args.time_out)] if args.time_out else []
    return flags + (["--seed", str(seed)] if seeded else [])


def box_seed(exp: Expectation, args: argparse.Namespace, seed: int) -> int | None:
    """The box's own seed: a random combination's is the run's; a broken box's base comes from --base-seed."""
    if exp.name == RANDOM:
        return seed
    base = getattr(args, "base_seed", 0)
    if exp.role != "box" or exp.conforming or not base:
        return None
    return (zlib.crc32(exp.name.encode()) + base) % 1_000_000


def target_args(line: str) -> list[str]:
    """The suite's flags from the box's first line: tcp, udp, stream ADDRESS pairs, then ``args`` FLAGS."""
    words = line.split()
    head, _, flags = " ".join(words[1:]).partition(" args ")
    pairs = head.split()
    where = {"tcp": "--target", "udp": "--udp-target", "stream": "--stream-target"}
    out = []
    for kind, address in zip(pairs[::2], pairs[1::2]):
        out += [where[kind], address] if kind in where else []
    return out + flags.split()


def run_box(exp: Expectation, args: argparse.Namespace, out: Path, seed: int, seeded: bool) -> Row:
    row = _new_row(exp, seed)
    row.box_seed = box_seed(exp, args, seed)
    work = out / f"{exp.name}-{seed}"
    work.mkdir(parents=True, exist_ok=True)
    box_cmd = [sys.executable, "-m", "tests.impls.box", exp.name, "--port", "0"]
    box_cmd += ["--seed", str(row.box_seed)] if row.box_seed is not None else []
    box_cmd += ["--time-out", str(args.time_out)] if args.time_out else []
    box = Proc(box_cmd, work, "box")
    line = box.first_line(20)
    if line is None or not line.startswith("listening tcp "):
        row.notes.append(f"box did not start: {box.last_line() or line!r}")
        box.stop()
        return _finish(row, box)
    row.knobs = _knobs(exp, row.box_seed)
    target = target_args(line)
    suite = Proc(suite_command() + ["run", *target, "--quiet", "--report-dir", str(work / "report"),
                                    "--pcap-dir", str(work / "pcaps"), *exp.suite_args,
                                    *_suite_flags(args, seed, seeded)], work, "suite")
    row.exit = suite.wait(args.limit, args.mem_limit)
    note = box.stop()
    if note:
        row.notes.append(f"box {note}")
    return _finish(row, suite, work / "report")


def run_robot(exp: Expectation, args: argparse.Namespace, out: Path, seed: int, seeded: bool) -> Row:
    from .robot import variant  # the robot's own knobs, for the flags certify-robot needs (same code as the process)

    row = _new_row(exp, seed)
    row.box_seed = seed if exp.name == RANDOM else None
    robot = variant(exp.name, row.box_seed)
    row.knobs = robot.description.removeprefix("a random legal combination: ") if exp.name == RANDOM else ""
    work = out / f"{exp.name}-{seed}"
    work.mkdir(parents=True, exist_ok=True)
    flags = robot.choices.suite_args() if exp.name == RANDOM else ()
    suite = Proc(suite_command() + ["certify-robot", "--listen", "127.0.0.1:0", "--no-udp", "--quiet",
                                    "--wait", "60", "--max-session", str(min(args.limit, 300)),
                                    "--report-dir", str(work / "report"), "--pcap-dir", str(work / "pcaps"),
                                    *exp.suite_args, *flags, *_suite_flags(args, seed, False)], work, "suite")
    line = suite.first_line(30)  # certify-robot has no fuzz cases and so no --seed: a seed is a plain repeat
    if line is None or not line.startswith("listening tcp "):
        row.notes.append(f"certify-robot did not start: {suite.last_line() or line!r}")
        suite.kill("did not start")
        return _finish(row, suite)
    robot_cmd = [sys.executable, "-m", "tests.impls.robot", exp.name, "--target", line.split()[2]]
    robot_cmd += ["--seed", str(seed)] if exp.name == RANDOM else []
    if args.time_out:
        robot_cmd += ["--time-out", str(args.time_out)]
    player = Proc(robot_cmd, work, "robot")
    robot_rc = player.wait(120)
    row.notes.append(f"robot exit {robot_rc if robot_rc is not None else player.killed}"
                     + (f": {player.last_line()}" if robot_rc else ""))
    row.exit = suite.wait(args.limit, args.mem_limit)
    return _finish(row, suite, work / "report")


def _knobs(exp: Expectation, seed: int | None) -> str:
    from .box import describe, variant  # the box's own description of its knobs (same code as the process)

    return describe(variant(exp.name, seed).choices) if seed is not None else ""


def _finish(row: Row, suite: Proc, report: Path | None = None) -> Row:
    row.wall_s = round(time.monotonic() - suite.t0, 1)
    row.peak_rss_mb = round(suite.peak_kb / 1024, 1)
    if suite.killed:
        row.notes.append(f"suite {suite.killed}")
    elif row.exit not in (0, 1):
        row.notes.append(f"suite: {suite.last_line()}")
    if report is not None:
        _read_summary(row, report)
    if not row.judgement:
        _judge(row, None, ())
    return row


def format_table(rows: list[Row]) -> str:
    head = "| name | role | kind | expected | judgement | exit | wall s | peak RSS MB | totals | first FAIL/NON-STRICT | root_causes | notes |"
    lines = [head, "|" + "---|" * (head.count("|") - 1)]
    for r in rows:
        totals = " ".join(f"{SHORT.get(k, k)}{v}" for k, v in r.totals.items())
        causes = "(no key)" if r.root_causes is None else ("; ".join(r.root_causes) or "[]")
        name = r.name if not r.seed else f"{r.name}#{r.seed}"
        notes = r.notes + ([f"knobs: {r.knobs}"] if r.knobs else [])
        if r.box_seed is not None and r.name != RANDOM:
            notes.append(f"base seed {r.box_seed}")
        lines.append(f"| {name} | {r.role} | {r.kind} | {r.expected} | {r.judgement} | {r.exit} | {r.wall_s} | "
                     f"{r.peak_rss_mb} | {totals} | {'<br>'.join(r.first)} | {causes} | {'; '.join(notes)} |")
    return "\n".join(lines)


def write_table(rows: list[Row], out: Path) -> int:
    table = format_table(rows)
    (out / "matrix.md").write_text(table + "\n")
    (out / "matrix.json").write_text(json.dumps([asdict(r) for r in rows], indent=1) + "\n")
    print(table)
    print(f"\nreports: {out}")
    return 0 if all(r.judgement == "ok" for r in rows) else 1


def rejudge(out: Path) -> int:
    """Judge an earlier matrix run again (e.g. after the expectations or the suite's summary changed)."""
    try:
        rows = [Row(**r) for r in json.loads((out / "matrix.json").read_text())]
    except (OSError, ValueError, TypeError) as exc:
        print(f"error: cannot read {out / 'matrix.json'}: {exc}", file=sys.stderr)
        return 2
    for row in rows:
        row.expected = _new_row(expectation(row.name, row.role), row.seed).expected
        row.first, row.root_causes, row.judgement = [], None, ""
        row.notes = [n for n in row.notes if not n.startswith(("no summary.json", "root_causes is empty"))]
        report = out / f"{row.name}-{row.seed}" / "report"
        if report.exists():
            _read_summary(row, report)
        if not row.judgement:
            _judge(row, None, ())
    return write_table(rows, out)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m tests.impls.matrix", description=__doc__.split("\n\n")[0])
    parser.add_argument("--only", nargs="+", metavar="NAME", help="only these implementations")
    parser.add_argument("--seeds", type=int, default=1, metavar="N",
                        help="runs per implementation: boxes with run --seed 1..N (fuzz cases), robots repeated")
    parser.add_argument("--sample", type=int, default=0, metavar="N",
                        help="run N random legal combinations instead (boxes; robots with --role robot)")
    parser.add_argument("--seed", type=int, default=1, metavar="S", help="--sample draws its combinations from S")
    parser.add_argument("--role", choices=("box", "robot"), default="box", help="what --sample samples (default box)")
    parser.add_argument("--base-seed", type=int, default=1, metavar="B",
                        help="broken boxes sit on a random legal base drawn from B and their name (0: documented base)")
    parser.add_argument("--time-out", type=int, default=0, metavar="MS", help="time_out for the suite and robots")
    parser.add_argument("--jobs", type=int, default=1, help="implementations run at once (default 1)")
    parser.add_argument("--limit", type=float, default=1800, metavar="S", help="hard bound per suite run (s)")
    parser.add_argument("--mem-limit", type=float, default=4096, metavar="MB", help="suite RSS cap (default 4096)")
    parser.add_argument("--out", type=Path, help="where reports go (default reports/impls-matrix-<time>)")
    parser.add_argument("--through-monitor", type=int, nargs=2, metavar=("R", "B"),
                        help="instead: R random legal robots x B random legal boxes through monitor, analyze on the "
                             "capture, plus the broken ones on random bases (tests/impls/pairs.py; --seed, --jobs)")
    parser.add_argument("--rejudge", type=Path, metavar="DIR",
                        help="run nothing: re-read DIR's reports, judge them again and rewrite DIR's table")
    args = parser.parse_args(argv)
    if args.through_monitor:
        from .pairs import main as pairs_main

        return pairs_main(["--robots", str(args.through_monitor[0]), "--boxes", str(args.through_monitor[1]),
                           "--broken", "--seed", str(args.seed), "--jobs", str(args.jobs)]
                          + (["--out", str(args.out)] if args.out else []))
    if args.rejudge is not None:
        return rejudge(args.rejudge)
    names = args.only or list(EXPECTATIONS)
    unknown = [n for n in names if n not in EXPECTATIONS]
    if unknown or not 1 <= args.seeds <= 100 or not 1 <= args.jobs <= 8 or args.limit <= 0 \
            or not 0 <= args.sample <= 1000 or args.base_seed < 0:
        print(f"error: {'unknown implementation(s): ' + ', '.join(unknown) if unknown else 'bad --seeds/--jobs/--limit/--sample/--base-seed'}",
              file=sys.stderr)
        return 2
    out = args.out or ROOT / "reports" / time.strftime("impls-matrix-%Y%m%d-%H%M%S")
    out.mkdir(parents=True, exist_ok=True)
    if args.sample:
        jobs = [(expectation(RANDOM, args.role), seed) for seed in sample_seeds(args.seed, args.sample)]
    else:
        seeds = [0] if args.seeds == 1 else list(range(1, args.seeds + 1))  # 0: the suite's own default
        jobs = [(EXPECTATIONS[n], seed) for n in names for seed in seeds]
    t0 = time.monotonic()

    def one(job: tuple[Expectation, int]) -> Row:
        exp, seed = job
        runner = run_box if exp.role == "box" else run_robot
        row = runner(exp, args, out, seed, seed > 0)
        print(f"{row.name:<20} {row.kind:<10} {row.judgement:<40} exit {row.exit} {row.wall_s:>7.1f} s "
              f"{row.peak_rss_mb:>7.1f} MB", file=sys.stderr, flush=True)
        return row

    with ThreadPoolExecutor(max_workers=args.jobs) as pool:
        rows = list(pool.map(one, jobs))
    status = write_table(rows, out)
    clean = sum(r.judgement == "ok" for r in rows)
    walls = sorted(r.wall_s for r in rows)
    print(f"{len(rows)} run, {clean} as expected, {len(rows) - clean} not; wall per run min {walls[0]} s, "
          f"median {walls[len(walls) // 2]} s, max {walls[-1]} s; {time.monotonic() - t0:.0f} s in all "
          f"at --jobs {args.jobs}")
    return status


def sample_seeds(seed: int, n: int) -> list[int]:
    """The seeds of ``n`` random combinations drawn from ``seed`` (each names one box or robot)."""
    rng = random.Random(seed)
    return [rng.randrange(1, 1_000_000) for _ in range(n)]


if __name__ == "__main__":
    sys.exit(main())

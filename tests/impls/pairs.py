"""Every judge over the legal space: robot ↔ ``monitor`` ↔ box pairs, and ``analyze`` on the capture.

``python -m tests.impls.pairs --robots R --boxes B --seed S [--broken] [--with-run] [--jobs J]``
(also ``python -m tests.impls.matrix --through-monitor R B``)

Draws R random legal robots and B random legal boxes from ``--seed`` and plays each robot
against each box THROUGH ``isight-conformance monitor`` (R × B pairs, each in its own
processes: the box, the monitor, the robot); then ``analyze`` reads the monitor's pcapng
ring. Each sampled robot is also certified by ``certify-robot`` (once), and with
``--with-run`` each sampled box is judged by ``run`` (once). ``--broken`` adds the broken
robots and boxes whose defect legal traffic shows (:data:`PASSIVE_ROBOTS`,
:data:`PASSIVE_BOXES`), each on a random legal base, against a random legal partner.

The four judges must agree:

* a legal pair is clean in ``monitor`` and ``analyze`` (exit 0, no FAIL, ERROR or
  NON-STRICT case), its robot in ``certify-robot`` and its box in ``run``;
* a broken robot (box) is caught on its side with one of its clauses at its level by
  ``monitor`` and ``analyze`` (a failing ``OBS-<clause>-robot`` case, and no failing case
  of the other side), and by ``certify-robot`` (``run``).

T2's jitter on a loaded machine is the scheduling of a Python robot, not a legal choice:
the passive judges and certify-robot get the matrix's loose ``--jitter-tolerance 600
--rate-tolerance 25`` for every robot (a robot streaming 30 % slow is still below it).
The table goes to ``OUT/pairs.md`` and ``OUT/pairs.json``.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import asdict, dataclass, field
from pathlib import Path

from .expectations import EXPECTATIONS, Expectation, expectation, judge
from .matrix import ROOT, Proc, sample_seeds, target_args

#: broken robots whose defect a legal box's traffic shows (stream-open holds its stream 30 s: left out)
PASSIVE_ROBOTS = ("transfer-10", "index-1", "cycle-on-first", "nan-pose", "slow-stream", "little-floats")
#: broken boxes whose defect a legal robot's traffic shows (the others need malformed input or many sessions)
PASSIVE_BOXES = ("swapped-version", "wrong-transfer-type", "late-cycle-on", "dead")
#: the broken robots' partner: a conforming box that lets every legal session run (no refusal, extension E)
PARTNER_BOX = "resync-fine"
LOOSE = ("--jitter-tolerance", "600", "--rate-tolerance", "25")
RANDOM = "random"
#: the suite of this checkout (``python -m conformance`` in the repository's root), not an installed one
SUITE = [sys.executable, "-m", "conformance"]
FAILING = ("FAIL", "ERROR", "NON-STRICT")


@dataclass
class Side:
    name: str  # "random" or a broken variant's name
    seed: int  # the combination (random) or the random legal base (broken)

    @property
    def label(self) -> str:
        return f"{self.name}#{self.seed}"

    @property
    def broken(self) -> bool:
        return self.name != RANDOM and not EXPECTATIONS[self.name].conforming


@dataclass
class PairRow:
    robot: str
    box: str
    kind: str  # legal | broken-robot | broken-box
    expected: str
    verdicts: dict[str, str] = field(default_factory=dict)  # judge -> "clean" or its failing cases
    exits: dict[str, int | None] = field(default_factory=dict)
    judgement: str = ""
    wall_s: float = 0.0
    notes: list[str] = field(default_factory=list)


def _failing(report: Path) -> dict[str, str] | None:
    try:
        doc = json.loads((report / "summary.json").read_text())
    except (OSError, ValueError):
        return None
    return {c["id"]: c["verdict"] for c in doc.get("cases", []) if c.get("verdict") in FAILING}


def _robot_args(side: Side) -> list[str]:
    return ["--seed", str(side.seed)] if side.name == RANDOM else ["--base-seed", str(side.seed)]


def _robot_flags(side: Side) -> list[str]:
    from .robot import variant  # the robot's own flags, as the process computes them

    chosen = variant(side.name, side.seed if side.name == RANDOM else None,
                     side.seed if side.name != RANDOM else None)
    return list(chosen.choices.suite_args())


def _box(side: Side, work: Path) -> tuple[Proc, str | None]:
    cmd = [sys.executable, "-m", "tests.impls.box", side.name, "--port", "0", "--seed", str(side.seed), "--for-robot"]
    box = Proc(cmd, work, "box")
    return box, box.first_line(20)


def _profile_flags(target: list[str]) -> list[str]:
    """The box's profile flags without its addresses (--target, --udp-target, --stream-target and their values)."""
    out, skip = [], False
    for word in target:
        if skip:
            skip = False
        elif word in ("--target", "--udp-target", "--stream-target"):
            skip = True
        else:
            out.append(word)
    return out


def judge_side(failing: dict[str, str] | None, exit_code: int | None, broken: Side | None, role: str) -> str:
    """"ok" or what is wrong, for one passive judge's cases (``OBS-<clause>-<side>``)."""
    if failing is None or exit_code is None:
        return f"NO RESULT (exit {exit_code})"
    if broken is None:
        return "ok" if exit_code == 0 and not failing else f"FALSE ALARM ({', '.join(sorted(failing)) or exit_code})"
    exp = expectation(broken.name, role)
    other = "box" if role == "robot" else "robot"
    wrong = sorted(k for k in failing if k.endswith(f"-{other}"))
    if wrong:
        return f"WRONG SIDE ({', '.join(wrong)})"
    hits = [k for k, v in failing.items() if k.endswith(f"-{role}") and k.split("-")[1] in exp.clauses and v == exp.level]
    if hits:
        return "ok"
    return f"MISSED ({', '.join(f'{k} {v}' for k, v in sorted(failing.items())) or 'clean'}; expected " \
           f"{'/'.join(exp.clauses)} {exp.level})"


def run_pair(robot: Side, box: Side, args: argparse.Namespace, out: Path) -> PairRow:
    kind = "broken-robot" if robot.broken else "broken-box" if box.broken else "legal"
    broken = robot if robot.broken else box if box.broken else None
    role = "robot" if robot.broken else "box"
    expected = "clean" if broken is None else \
        f"{role} {'/'.join(expectation(broken.name, role).clauses)} {expectation(broken.name, role).level}"
    row = PairRow(robot.label, box.label, kind, expected)
    work = out / f"{robot.label}__{box.label}".replace("#", "-")
    work.mkdir(parents=True, exist_ok=True)
    t0 = time.monotonic()
    proc, line = _box(box, work)
    if line is None or not line.startswith("listening tcp "):
        row.notes.append(f"box did not start: {proc.last_line() or line!r}")
        proc.stop()
        row.judgement = "NO RESULT"
        return row
    target = target_args(line)
    upstream = target[target.index("--target") + 1]
    profile = _profile_flags(target)
    flags = [*profile, *_robot_flags(robot), *LOOSE]
    monitor = Proc(SUITE + ["monitor", "--listen", "127.0.0.1:0", "--upstream", upstream, "--quiet",
                                      "--checkpoint", "0", "--report-dir", str(work / "monitor"),
                                      "--pcap-dir", str(work / "pcaps"), *flags], work, "monitor")
    mline = monitor.first_line(60)
    if mline is None or not mline.startswith("listening tcp "):
        row.notes.append(f"monitor did not start: {monitor.last_line() or mline!r}")
        monitor.kill("did not start")
        proc.stop()
        row.judgement = "NO RESULT"
        return row
    player = Proc([sys.executable, "-m", "tests.impls.robot", robot.name, "--target", mline.split()[2],
                   "--duration", str(args.duration), *_robot_args(robot)], work, "robot")
    robot_rc = player.wait(120)
    row.notes.append(f"robot exit {robot_rc if robot_rc is not None else player.killed}")
    time.sleep(0.5)  # the last closes pass through
    note = monitor.stop(grace=60)
    if note:
        row.notes.append(f"monitor {note}")
    row.exits["monitor"] = monitor.rc
    box_note = proc.stop()
    if box_note:
        row.notes.append(f"box {box_note}")
    pcaps = sorted((work / "pcaps").glob("*.pcapng"))
    port = upstream.rsplit(":", 1)[1]
    analyzer = Proc(SUITE + ["analyze", *(str(p) for p in pcaps[:1]), "--port", port, "--no-heuristic",
                                       "--quiet", "--report-dir", str(work / "analyze"), *flags], work, "analyze")
    row.exits["analyze"] = analyzer.wait(300)
    results = {"monitor": judge_side(_failing(work / "monitor"), row.exits["monitor"], broken, role),
               "analyze": judge_side(_failing(work / "analyze"), row.exits["analyze"], broken, role)}
    for judge_name in ("monitor", "analyze"):
        failing = _failing(work / judge_name)
        row.verdicts[judge_name] = "clean" if failing == {} else ", ".join(f"{k} {v}" for k, v in sorted((failing or {}).items()))
    row.judgement = "ok" if all(v == "ok" for v in results.values()) else \
        "; ".join(f"{k}: {v}" for k, v in results.items() if v != "ok")
    if broken is not None and all(v.startswith("MISSED (clean") for v in results.values()) and robot_rc:
        # the partner refused legally before the defect could show (e.g. a box answering ProgIdx 409)
        row.judgement = f"NOT EXERCISED (the robot stopped: {player.last_line() or robot_rc})"
    row.wall_s = round(time.monotonic() - t0, 1)
    return row


def certify(robot: Side, args: argparse.Namespace, out: Path) -> tuple[str, str]:
    """certify-robot on the robot alone: ("ok" or what is wrong, its failing cases)."""
    work = out / f"certify-{robot.label}".replace("#", "-")
    work.mkdir(parents=True, exist_ok=True)
    suite = Proc(SUITE + ["certify-robot", "--listen", "127.0.0.1:0", "--no-udp", "--quiet", "--wait", "60",
                                    "--max-session", "120", "--report-dir", str(work / "report"),
                                    "--pcap-dir", str(work / "pcaps"), *_robot_flags(robot), *LOOSE], work, "suite")
    line = suite.first_line(60)
    if line is None or not line.startswith("listening tcp "):
        suite.kill("did not start")
        return f"NO RESULT (certify-robot did not start: {suite.last_line()})", ""
    player = Proc([sys.executable, "-m", "tests.impls.robot", robot.name, "--target", line.split()[2],
                   "--duration", str(args.duration), *_robot_args(robot)], work, "robot")
    player.wait(120)
    rc = suite.wait(300)
    return _judged(expectation(robot.name, "robot"), rc, work / "report")


def _judged(exp: Expectation, rc: int | None, report: Path) -> tuple[str, str]:
    """The matrix's own judgement of a suite run (its exit, totals and first root cause)."""
    try:
        doc = json.loads((report / "summary.json").read_text())
    except (OSError, ValueError):
        return f"NO RESULT (exit {rc}, no summary.json)", ""
    failing = [c for c in doc.get("cases", []) if c.get("verdict") in FAILING]
    first = tuple(failing[0].get("clauses", ())) if failing else ()
    totals = {k: v for k, v in doc.get("totals", {}).items() if v}
    shown = ", ".join(f"{c['id']} {c['verdict']}" for c in failing[:4]) or "clean"
    return judge(exp, rc, totals, doc.get("root_causes"), first), shown


def run_suite_on_box(box: Side, args: argparse.Namespace, out: Path) -> tuple[str, str]:
    """``run`` on the box alone (``--with-run``)."""
    work = out / f"run-{box.label}".replace("#", "-")
    work.mkdir(parents=True, exist_ok=True)
    proc, line = _box(box, work)
    if line is None:
        proc.stop()
        return "NO RESULT (box did not start)", ""
    suite = Proc(SUITE + ["run", *target_args(line), "--quiet", "--report-dir", str(work / "report"),
                                    "--pcap-dir", str(work / "pcaps")], work, "suite")
    rc = suite.wait(1800, 4096)
    proc.stop()
    return _judged(expectation(box.name, "box"), rc, work / "report")


def plan(args: argparse.Namespace) -> list[tuple[Side, Side]]:
    robots = [Side(RANDOM, s) for s in sample_seeds(args.seed, args.robots)]
    boxes = [Side(RANDOM, s) for s in sample_seeds(args.seed + 7919, args.boxes)]
    pairs = [(r, b) for r in robots for b in boxes]
    if args.broken:
        bases = sample_seeds(args.seed + 104729, len(PASSIVE_ROBOTS) + len(PASSIVE_BOXES))
        partners = sample_seeds(args.seed + 15485863, len(bases))
        for i, name in enumerate(PASSIVE_ROBOTS):  # a box that lets the session run: the defect must show
            pairs.append((Side(name, bases[i]), Side(PARTNER_BOX, 0)))
        for j, name in enumerate(PASSIVE_BOXES, len(PASSIVE_ROBOTS)):
            pairs.append((Side(RANDOM, partners[j]), Side(name, bases[j])))
    return pairs


def format_table(rows: list[PairRow], side_results: dict[str, tuple[str, str]]) -> str:
    lines = ["| robot | box | kind | expected | judgement | monitor | analyze | certify-robot | run | wall s | notes |",
             "|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        cert = side_results.get(f"certify {r.robot}", ("-", ""))
        run = side_results.get(f"run {r.box}", ("-", ""))
        lines.append(f"| {r.robot} | {r.box} | {r.kind} | {r.expected} | {r.judgement} | {r.verdicts.get('monitor', '-')} "
                     f"| {r.verdicts.get('analyze', '-')} | {cert[0]} | {run[0]} | {r.wall_s} | {'; '.join(r.notes)} |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m tests.impls.pairs", description=__doc__.split("\n\n")[0])
    parser.add_argument("--robots", type=int, default=2, metavar="R", help="random legal robots (default 2)")
    parser.add_argument("--boxes", type=int, default=2, metavar="B", help="random legal boxes (default 2)")
    parser.add_argument("--seed", type=int, default=1, metavar="S", help="draws the robots, boxes and bases")
    parser.add_argument("--broken", action="store_true", help="add the broken robots and boxes legal traffic shows")
    parser.add_argument("--with-run", action="store_true", help="also judge each sampled box with run (slow)")
    parser.add_argument("--no-certify", action="store_true", help="skip certify-robot on each sampled robot")
    parser.add_argument("--duration", type=float, default=1.5, metavar="S", help="robots' trajectory (default 1.5)")
    parser.add_argument("--jobs", type=int, default=1, help="pairs run at once (default 1)")
    parser.add_argument("--out", type=Path, help="where reports go (default reports/impls-pairs-<time>)")
    args = parser.parse_args(argv)
    if not (0 <= args.robots <= 100 and 0 <= args.boxes <= 100 and 1 <= args.jobs <= 8 and 0 < args.duration <= 60):
        print("error: --robots/--boxes 0..100, --jobs 1..8, --duration in (0, 60]", file=sys.stderr)
        return 2
    out = args.out or ROOT / "reports" / time.strftime("impls-pairs-%Y%m%d-%H%M%S")
    out.mkdir(parents=True, exist_ok=True)
    pairs = plan(args)
    t0 = time.monotonic()

    def one(pair: tuple[Side, Side]) -> PairRow:
        row = run_pair(pair[0], pair[1], args, out)
        print(f"{row.robot:<24} {row.box:<26} {row.kind:<12} {row.judgement:<40} {row.wall_s:>6.1f} s",
              file=sys.stderr, flush=True)
        return row

    side_results: dict[str, tuple[str, str]] = {}
    with ThreadPoolExecutor(max_workers=args.jobs) as pool:
        rows = list(pool.map(one, pairs))
        if not args.no_certify:
            robots = {r.label: r for r, _ in pairs}
            for label, res in zip(robots, pool.map(lambda r: certify(r, args, out), robots.values())):
                side_results[f"certify {label}"] = res
        if args.with_run:
            boxes = {b.label: b for _, b in pairs}
            for label, res in zip(boxes, pool.map(lambda b: run_suite_on_box(b, args, out), boxes.values())):
                side_results[f"run {label}"] = res
    table = format_table(rows, side_results)
    (out / "pairs.md").write_text(table + "\n")
    (out / "pairs.json").write_text(json.dumps({"pairs": [asdict(r) for r in rows], "sides": side_results},
                                               indent=1) + "\n")
    print(table)
    sides_ok = all(v[0].startswith("ok") for v in side_results.values())
    agree = sum(r.judgement == "ok" for r in rows)
    idle = sum(r.judgement.startswith("NOT EXERCISED") for r in rows)
    walls = sorted(r.wall_s for r in rows) or [0.0]
    print(f"\n{len(rows)} pair(s), {agree} as expected in monitor and analyze, {idle} not exercised; "
          f"{sum(v[0].startswith('ok') for v in side_results.values())}/{len(side_results)} certify-robot/run as expected; "
          f"wall per pair min {walls[0]} s, median {walls[len(walls) // 2]} s, max {walls[-1]} s; "
          f"{time.monotonic() - t0:.0f} s in all at --jobs {args.jobs}; reports: {out}")
    return 0 if agree + idle == len(rows) and sides_ok else 1


if __name__ == "__main__":
    sys.exit(main())

"""The independent robots: variants as data, and the command line.

``python -m tests.impls.robot --list`` lists them; ``python -m tests.impls.robot VARIANT
--target HOST:PORT`` plays one session against a box (e.g. ``isight-conformance
certify-robot``) and exits 0, or non-zero with one line on stderr; ``random --seed N``
plays a random legal combination of the robot's knobs (``--flags`` prints the
certify-robot flags it needs and exits). In-process::

    outcome = Robot(ROBOTS["canonical"].choices, ("127.0.0.1", port)).run()

A broken robot is a conforming one with exactly one defect; ``clause`` names it.
"""

from __future__ import annotations

import argparse
import signal
import sys
import threading
from dataclasses import dataclass, fields, replace
from typing import Any

from .robots import Outcome, Robot, RobotChoices, random_choices


@dataclass(frozen=True)
class RobotVariant:
    name: str
    choices: RobotChoices
    description: str
    clause: str | None = None  # the clause a broken robot breaks
    level: str = "FAIL"

    @property
    def conforming(self) -> bool:
        return self.clause is None

    @property
    def extension(self) -> bool:
        return self.choices.session == "E4"


_CANONICAL = RobotChoices()
_LIST = [
    RobotVariant("canonical", _CANONICAL,
                 "S1: connect, stream on (waits for the first pose answer), CycleOn, 2 s trajectory, CycleOff, "
                 "stream off (waits for the answers), disconnect; lock-step on the command connection"),
    RobotVariant("karel-calls", replace(_CANONICAL, pings="1", tolerance_at="start", tolerance_blocks="3",
                                        cmd_poses="both", read_late="late"),
                 "pings (00), tolerance with 3 blocks (25), stream on, a pose (23, ISIGHT(3,35)) and a register "
                 "pose (24, ISIGHT(3,36,PR_ID)) on the command connection, then S1; reads the stream's answers in "
                 "bursts every 0.5 s; closes the stream before the command connection"),
    RobotVariant("extension", replace(_CANONICAL, session="E4"),
                 "E4: ProgIdx (26) first, then S1, stream off, 1 s wait, result request (27)"),
    RobotVariant("transfer-10", replace(_CANONICAL, transfer=0x10),
                 "every frame carries transfer type 10 (box->robot)", "F3"),
    RobotVariant("index-1", replace(_CANONICAL, first_index=1), "block indexes start at 01", "B3"),
    RobotVariant("cycle-on-first", replace(_CANONICAL, session="cycle-on-first"),
                 "CycleOn before the stream connection is on", "S1"),
    RobotVariant("nan-pose", replace(_CANONICAL, nan_pose=True),
                 "one pose in the middle of the trajectory has x = NaN", "B4", "NON-STRICT"),
    RobotVariant("slow-stream", replace(_CANONICAL, rate_factor=0.7),
                 "streams 30 % below the declared rate (35 Hz for 50 Hz)", "T2"),
    RobotVariant("stream-45hz", replace(_CANONICAL, rate_factor=0.9),
                 "streams 10 % below the declared rate (45 Hz for 50 Hz): judged at --rate-tolerance 5", "T2"),
    RobotVariant("stream-open", replace(_CANONICAL, leave_stream_open=True),
                 "never closes the stream connection (holds it until the box closes it, at most 30 s)", "S5"),
    RobotVariant("no-wait", replace(_CANONICAL, no_wait=True),
                 "sends CycleOff 1 ms after CycleOn without waiting for CycleOn's answer (then reads both)", "A1"),
    RobotVariant("little-floats", replace(_CANONICAL, float_order="<"),
                 "pose and tolerance floats little-endian", "F4"),
]
ROBOTS: dict[str, RobotVariant] = {v.name: v for v in _LIST}
RANDOM = "random"


def variant(name: str, seed: int | None = None, base_seed: int | None = None) -> RobotVariant:
    """A robot by name; ``random`` with ``seed`` is a random legal combination of the knobs; a broken
    robot with ``base_seed`` carries its one defect on a random legal base (drawn from that seed)."""
    if name != RANDOM:
        found = ROBOTS[name]
        if base_seed is None or found.conforming:
            return found
        defect = {f.name: getattr(found.choices, f.name) for f in fields(RobotChoices)
                  if getattr(found.choices, f.name) != getattr(_CANONICAL, f.name)}
        base = random_choices(base_seed)
        return replace(found, choices=replace(base, **defect),
                       description=f"{found.description} (on the random legal base #{base_seed})")
    if seed is None:
        raise ValueError("the random robot needs --seed")
    choices = random_choices(seed)
    diff = [f"{k}={v}" for k, v in choices.knobs().items() if getattr(_CANONICAL, k) != v]
    return RobotVariant(f"random#{seed}", choices, "a random legal combination: " + (" ".join(diff) or "canonical"))


def _target(text: str) -> tuple[str, int]:
    host, sep, port = text.rpartition(":")
    if not sep or not host or not port.isdigit() or not 0 < int(port) < 65536:
        raise ValueError(f"--target must be HOST:PORT, not {text!r}")
    return host.strip("[]"), int(port)


def run_robot(name: str, target: tuple[str, int], seed: int | None = None, **overrides: Any) -> Outcome:
    """Play one session of robot ``name`` (every wait bounded)."""
    return Robot(replace(variant(name, seed).choices, **overrides), target).run()


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m tests.impls.robot", description=__doc__.split("\n\n")[0])
    parser.add_argument("variant", nargs="?", help="which robot (see --list), or 'random'")
    parser.add_argument("--seed", type=int, help="random: the combination")
    parser.add_argument("--base-seed", type=int, help="a broken robot: its random legal base")
    parser.add_argument("--flags", action="store_true", help="print the certify-robot flags the robot needs, exit")
    parser.add_argument("--target", default="127.0.0.1:9004", help="the box, HOST:PORT (default 127.0.0.1:9004)")
    parser.add_argument("--duration", type=float, default=2.0, help="primer trajectory seconds (default 2)")
    parser.add_argument("--rate", type=float, help="declared stream rate in Hz (default: the robot's, 50)")
    parser.add_argument("--time-out", type=int, default=5000, metavar="MS", help="time_out in ms (default 5000)")
    parser.add_argument("--vision-time-out", type=int, default=5000, metavar="MS", help="for 27 (default 5000)")
    parser.add_argument("--list", action="store_true", help="list the variants and exit")
    args = parser.parse_args(argv)
    if args.list:
        for v in ROBOTS.values():
            kind = "conforming" if v.conforming else f"broken [{v.clause}]"
            print(f"{v.name:<16} {kind:<14} {v.description}")
        return 0
    try:
        if args.variant not in ROBOTS and args.variant != RANDOM:
            raise ValueError(f"unknown robot {args.variant!r}; try --list")
        chosen = variant(args.variant, args.seed, args.base_seed)
        if args.flags:
            print(" ".join(chosen.choices.suite_args()))
            return 0
        target = _target(args.target)
        rate = chosen.choices.rate if args.rate is None else f"{args.rate:g}"
        if not 0 < args.duration <= 600 or not 0 < float(rate) <= 1000 or not 0 < args.time_out <= 600_000:
            raise ValueError("--duration, --rate and --time-out must be positive and sane")
    except ValueError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    choices = replace(chosen.choices, duration=args.duration, rate=rate,
                      time_out=args.time_out / 1000, vision_time_out=args.vision_time_out / 1000)
    robot = Robot(choices, target)
    result: list[Outcome] = []
    thread = threading.Thread(target=lambda: result.append(robot.run()), daemon=True)
    for sig in (signal.SIGTERM, signal.SIGINT):
        signal.signal(sig, lambda *_: robot.stop())
    thread.start()
    while thread.is_alive():
        thread.join(0.2)
    outcome = result[0] if result else Outcome(1, "the robot crashed")
    line = (f"{args.variant}: {outcome.reason}; poses sent {outcome.poses_sent}, answered {outcome.poses_answered}, "
            f"commands {outcome.commands}")
    print(line, file=sys.stderr if outcome.exit_code else sys.stdout)
    return outcome.exit_code


if __name__ == "__main__":
    sys.exit(main())

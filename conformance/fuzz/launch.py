"""The ``fuzz`` and ``replay`` commands' bodies: the box, the campaign, the replay and what they print.

Their parsers are :mod:`conformance.commands.fuzz` and :mod:`conformance.commands.replay`. Exit
status, like ``run``: 0 no failure, 1 a failure was found (fuzz) or a vector still fails (replay),
2 usage error or unreachable target.
"""

from __future__ import annotations

import argparse
import shlex
import sys
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING

from ..endpoints.bundled import Bundled, bundled_or_target
from ..harness.extension_probe import extension_for
from ..harness.target import Target, check_reachable
from ..harness.transcript import Transcript
from ..i18n import _
from ..model.exit_codes import EXIT_FAILED, EXIT_OK, EXIT_USAGE
from ..protocol import DEFAULT_PORT, Profile
from ..report.rundirs import default_run_dirs
from ..runtime.profile_options import profile_from_options
from .database import resolve_database
from .failure_lines import report_lines
from .gating import box_child
from .strategies import Strategies

if TYPE_CHECKING:
    from .result import CampaignResult

__all__ = ["main_fuzz", "main_replay"]


# -- shared -------------------------------------------------------------------------------------


def _parse_target(text: str | None) -> Target | None:
    return Target.parse(text, DEFAULT_PORT) if text else None


@contextmanager
def _box(args: argparse.Namespace, profile: Profile, name: str) -> Iterator[tuple[Target, Target | None, Bundled | None]]:
    """(target, udp target, the bundled box if started); raises SystemExit(2) when unreachable."""
    target, udp = _parse_target(args.target), _parse_target(args.udp_target)
    if target is not None:
        problem = check_reachable(target, profile.time_out_s)
        if problem:
            print(f"isight-conformance {name}: {problem}", file=sys.stderr)
            raise SystemExit(EXIT_USAGE)
    with bundled_or_target(target, udp, profile) as box:
        yield box


def _run_guarded(name: str, body: Callable[[], int]) -> int:
    try:
        return body()
    except SystemExit as exc:
        return int(exc.code or 0)
    except ValueError as exc:
        print(f"isight-conformance {name}: {exc}", file=sys.stderr)
        return EXIT_USAGE


# -- fuzz ---------------------------------------------------------------------------------------------


def main_fuzz(args: argparse.Namespace) -> int:
    return _run_guarded("fuzz", lambda: _fuzz(args))


def _fuzz(args: argparse.Namespace) -> int:
    from .campaign import Campaign, CampaignConfig

    profile = profile_from_options(args)
    database, db_label = resolve_database(args.database, args.database_shared)
    categories = tuple(c.strip() for c in (args.categories or "").split(",") if c.strip())
    known = Strategies(profile, udp=True).categories()  # checked before a box is started or a directory made
    unknown = [c for c in categories if c not in known]
    if unknown:
        raise ValueError(f"unknown fuzz categories {', '.join(unknown)}; choose from {', '.join(known)}")
    quiet = args.quiet
    with box_child(args.restart_cmd, _parse_target(args.target), profile.time_out_s) as child, \
            _box(args, profile, "fuzz") as (target, udp, box):
        try:  # once the target is known to answer: an unreachable one leaves no directories behind
            report_dir, pcap_dir = default_run_dirs(args.report_dir, args.pcap_dir, prefix="fuzz-")
        except OSError as exc:
            raise ValueError(f"cannot create the report directory: {exc}") from None
        extension, how = extension_for(args.extension, target, profile, Transcript(case_id="FUZZ-extension"))
        config = CampaignConfig(
            target=target, profile=profile, udp_target=udp, stream_target=_parse_target(args.stream_target),
            seed=args.seed, max_examples=args.max_examples if args.max_examples or args.duration else 5000,
            duration_s=args.duration, report_dir=report_dir, pcap_dir=pcap_dir, capture=args.capture,
            database=database, database_label=db_label, extension=extension, batch=args.batch,
            liveness_every=args.liveness_every, max_failures=args.max_failures, categories=categories,
            stateful_share=args.stateful_share, restart=child.restart if child else _restart(args, box),
            box=child, until_first=args.until_first, bundled=box is not None,
            log=(lambda line: None if line.startswith("fuzz: ") and " examples (" in line else print(line, flush=True))
            if quiet else (lambda line: print(line, flush=True)),
            command=" ".join(shlex.quote(a) for a in sys.argv),
        )
        if not quiet:
            print(f"fuzz: extension E {how}", flush=True)
        try:
            result = Campaign(config).run()
        except Exception as exc:  # the suite's own fault, never the box's
            print(f"isight-conformance fuzz: internal error: {type(exc).__name__}: {exc}", file=sys.stderr)
            return EXIT_USAGE
    _print_result(result, report_dir / "fuzz-summary.json")
    return EXIT_FAILED if result.failures else EXIT_OK


def _restart(args: argparse.Namespace, box: Bundled | None) -> Callable[[], None] | None:
    if args.restart_cmd:
        from .restart import restart_command

        return restart_command(args.restart_cmd)
    return box.restart if box is not None else None


def _print_result(result: CampaignResult, summary: Path) -> None:
    rate = result.examples_per_s or 0
    sessions = result.stateful
    print("fuzz: " + _("{examples} examples in {seconds} s ({rate}/s{frames}); {steps} session steps in {sessions} "
                       "sessions; {failures} failures; {kinds} kinds of NON-STRICT").format(
        examples=f"{result.examples:,}", seconds=f"{result.duration_s:.1f}", rate=f"{rate:,.0f}",
        frames=_(" frames") if sessions.steps else "", steps=f"{sessions.steps:,}", sessions=sessions.runs,
        failures=len(result.failures), kinds=len(result.non_strict)))
    cov = result.coverage["fraction"]
    line = ", ".join(f"{k} {v:.0%}" for k, v in cov.items())
    if sessions.coverage:
        line += _("; state transitions {reached}/{of}").format(reached=sessions.coverage["reached"],
                                                                of=sessions.coverage["of"])
    if result.restarts:
        line += _("; the box was restarted {n} times").format(n=result.restarts)
    print("fuzz: " + _("coverage: {coverage}").format(coverage=line))
    for obs in result.non_strict:
        print(f"  NON-STRICT [{obs.clause}] {obs.requirement} (×{obs.count}, first on {obs.hex[:80]})")
    for line in report_lines(result.failures):  # deaths (R2) first, with the box's last words
        print(line)
    if result.hint:
        print("fuzz: " + _("hint: {hint}").format(hint=_(result.hint)))
    print("fuzz: " + _("summary {path}; seed {seed}").format(path=summary, seed=result.seed))


# -- replay -------------------------------------------------------------------------------------------


def main_replay(args: argparse.Namespace) -> int:
    return _run_guarded("replay", lambda: _replay(args))


def _replay(args: argparse.Namespace) -> int:
    from ..diagnose.repro import is_repro, replay_repros
    from .replay import load_files, replay, summary_line

    profile = profile_from_options(args)
    repros = [f for f in args.files if is_repro(f)]  # rootcause-N.json: fixed / still present per root cause
    if repros:
        with _box(args, profile, "replay") as (target, _udp, _started):
            print(f"replay: {len(repros)} root-cause repro(s) to {target}; profile {profile.describe()}", flush=True)
            status = replay_repros(repros, target, profile, profile.time_out_s, lambda line: print(line, flush=True))
        args.files = [f for f in args.files if f not in repros]
        if not args.files:
            return EXIT_OK if status == 0 else EXIT_FAILED
        rest = _replay(args)
        return max(rest, EXIT_FAILED if status else EXIT_OK)
    try:
        vectors = load_files(args.files, args.tc or ())
    except (OSError, ValueError, KeyError) as exc:
        print(f"isight-conformance replay: cannot read the vectors: {exc}", file=sys.stderr)
        return EXIT_USAGE
    if not vectors:
        print("isight-conformance replay: no vectors selected", file=sys.stderr)
        return EXIT_USAGE
    with _box(args, profile, "replay") as (target, udp, _box_started):
        transcript = Transcript(case_id="REPLAY")
        extension, how = extension_for(args.extension, target, profile, transcript)
        print(f"replay: {len(vectors)} vectors to {target}" + (f", UDP {udp}" if udp else "")
              + f"; profile {profile.describe()}; extension E {how}", flush=True)
        results = replay(vectors, target, profile, udp_target=udp, extension=extension,
                         one_connection=args.one_connection, settle_s=args.settle_ms / 1000, transcript=transcript,
                         log=lambda line: print("  " + line, flush=True))
    print(summary_line(results))
    return EXIT_FAILED if any(r.failing for r in results) else EXIT_OK

"""``isight-conformance certify-robot``: the suite becomes the AI Box and judges the robot.

The first line on stdout is ``listening tcp HOST:PORT udp HOST:PORT`` (so ``--listen
HOST:0`` can be scripted); then, unless ``--quiet``, one line per connection and
session event; at the end the table of cases that did not pass, the overall line and
where the reports are. Exit status: 0 no FAIL/ERROR, 1 FAIL/ERROR (or interrupted),
2 usage error, cannot listen, or no robot connected within ``--wait``.
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import dataclasses
import shlex
import signal
import sys
from pathlib import Path

from ..acceptance.manifest import seal
from ..acceptance.record import add_acceptance_options, from_args
from ..certify.certification import CertifyOutcome, ListenError, certify
from ..certify.latency import parse_latency
from ..certify.records import INJECTIONS, CertifyConfig
from ..i18n import N_, _
from ..model.exit_codes import EXIT_USAGE
from ..report.rundirs import default_run_dirs, drop_if_empty
from ..runtime.profile_options import profile_from_options
from ..runtime.settings import DEFAULT_SEED, SUITE_OPTIONS
from .options import add_profile_group, parse_listen
from .registry import Command

DEFAULT_LISTEN = "127.0.0.1:9004"
#: ``--extension auto|on|off``, spelt as ``run`` spells it; auto (None) judges the session the robot runs
EXTENSION_MODES: tuple[str, ...] = tuple(dict(SUITE_OPTIONS)["--extension"]["choices"])
EXTENSION_FORCED: dict[str, bool | None] = {"auto": None, "on": True, "off": False}


def add_arguments(p: argparse.ArgumentParser) -> None:
    net = p.add_argument_group("listening")
    net.add_argument("--listen", default=DEFAULT_LISTEN, metavar="HOST:PORT",
                     help=_("address to listen on, TCP and UDP (default: 127.0.0.1:9004; a real controller needs "
                          "0.0.0.0:9004; port 0 picks a free one)"))
    net.add_argument("--no-udp", action="store_true", help=_("listen on TCP only"))
    run = p.add_argument_group("the robot's sessions")
    run.add_argument("--sessions", type=int, default=1, metavar="N", help=_("sessions to judge before ending (default: 1)"))
    run.add_argument("--wait", type=float, default=120.0, metavar="S",
                     help=_("seconds to wait for the robot to connect, and the longest silence of a session (default: 120)"))
    run.add_argument("--linger", type=float, default=5.0, metavar="S",
                     help=_("[S5] seconds a connection may stay open after the command connection closed (default: 5)"))
    run.add_argument("--max-session", type=float, default=600.0, metavar="S",
                     help=_("a session is cut off after S seconds (default: 600)"))
    run.add_argument("--extension", choices=EXTENSION_MODES, default="auto", nargs="?", const="on",
                     help=_("[E4] the revision's session (ProgIdx first, result request after Send_Pos_Off): judge "
                          "each session by what the robot sends (auto, default), expect it (on; --extension alone), "
                          "or judge S1 only (off)"))
    run.add_argument("--answer-latency", default=None, metavar="MIN-MAX",
                     help=_("[A1, T1] answer CycleOn, CycleOff and the result request after a latency drawn from "
                          "MIN-MAX ms, as a real box takes time to start and stop a detection (default: 100-400, "
                          "inside time_out); 0 answers at once"))
    run.add_argument("--seed", type=int, default=DEFAULT_SEED, metavar="N",
                     help=_("seed of the answer latencies (default %(default)s; a run repeats with its seed)"))
    run.add_argument("--inject", action="append", default=[], choices=list(INJECTIONS), metavar="WHAT",
                     help="box behaviour to see how the robot copes (INFORMATIONAL; repeatable): "
                          + "; ".join(f"{k}: {v}" for k, v in INJECTIONS.items()).replace("%", "%%"))
    run.add_argument("--rate-tolerance", type=float, default=10.0, metavar="PCT",
                     help=_("[T2] mean and per-second stream rate within PCT %% of --pose-rate (default: 10)"))
    run.add_argument("--jitter-tolerance", type=float, default=50.0, metavar="PCT",
                     help=_("[T2] p99 |interval - 1/rate| within PCT %% of the period (default: 50)"))
    out = p.add_argument_group("reports")
    out.add_argument("--report-dir", type=Path, default=None, metavar="DIR",
                     help=_("summary.json, junit.xml, report.html (default: reports/<timestamp>)"))
    out.add_argument("--pcap-dir", type=Path, default=None, metavar="DIR",
                     help=_("one pcapng per connection and per session (default: pcaps/<timestamp>)"))
    out.add_argument("--quiet", action="store_true", help=_("no line per connection event (for CI logs)"))
    add_profile_group(p, "profile (--pose-rate is the rate the robot declares)")
    add_acceptance_options(p.add_argument_group("acceptance (one package per run: see docs/REPORTS.md)").add_argument,
                           declared=False)


def config_from_args(args: argparse.Namespace) -> CertifyConfig:
    """The run's settings, all checked before the report and pcap directories are made."""
    host, port = parse_listen(args.listen)
    config = CertifyConfig(
        host=host, port=port, udp=not args.no_udp, profile=profile_from_options(args), sessions=args.sessions,
        wait_s=args.wait, linger_s=args.linger, max_session_s=args.max_session, extension=EXTENSION_FORCED[args.extension],
        inject=tuple(dict.fromkeys(args.inject)), rate_tolerance=args.rate_tolerance / 100.0,
        jitter_tolerance=args.jitter_tolerance / 100.0,
        answer_latency_ms=None if args.answer_latency is None else parse_latency(args.answer_latency), seed=args.seed,
        command=" ".join(shlex.quote(a) for a in sys.argv),
    )
    acceptance = from_args(args)
    report_dir, pcap_dir = default_run_dirs(args.report_dir, args.pcap_dir)
    return dataclasses.replace(config, report_dir=report_dir, pcap_dir=pcap_dir, acceptance=acceptance.to_dict())


def _made_dirs(args: argparse.Namespace, config: CertifyConfig) -> list[Path | None]:
    """The run directories this run made itself (not the ones given with --report-dir / --pcap-dir)."""
    return [d for d, given in ((config.report_dir, args.report_dir), (config.pcap_dir, args.pcap_dir)) if given is None]


async def _main(config: CertifyConfig, quiet: bool) -> CertifyOutcome:
    loop = asyncio.get_running_loop()
    holder: list = []
    installed = []

    def ready(listener) -> None:
        holder.append(listener)
        for sig in (signal.SIGINT, signal.SIGTERM):
            with contextlib.suppress(NotImplementedError, RuntimeError, ValueError):
                loop.add_signal_handler(sig, listener.stop, f"stopped by signal {sig.name}")
                installed.append(sig)

    def event(text: str) -> None:
        if not quiet:
            print(text, flush=True)

    try:
        return await certify(config, on_listening=lambda line: print(line, flush=True), on_event=event,
                             listener_ready=ready)
    finally:
        for sig in installed:
            loop.remove_signal_handler(sig)


def main_certify(args: argparse.Namespace) -> int:
    from rich.console import Console

    from ..endpoints.loop import run_loop
    from ..report.terminal import print_final_table

    try:
        config = config_from_args(args)
    except (ValueError, OSError) as exc:  # OSError: the report directories cannot be created
        print(f"isight-conformance certify-robot: {exc}", file=sys.stderr)
        return EXIT_USAGE
    try:
        outcome: CertifyOutcome = run_loop(_main(config, args.quiet))
    except ListenError as exc:
        drop_if_empty(*_made_dirs(args, config))
        print(f"isight-conformance certify-robot: cannot listen on {args.listen}: {exc.strerror or exc}", file=sys.stderr)
        return EXIT_USAGE
    except OSError as exc:  # writing the reports or pcaps
        print(f"isight-conformance certify-robot: {exc.filename or ''}: {exc.strerror or exc}", file=sys.stderr)
        return EXIT_USAGE
    if outcome.suite is None:  # no session to judge (no robot came): nothing was written
        drop_if_empty(*_made_dirs(args, config))
        print(f"isight-conformance certify-robot: {outcome.reason}", file=sys.stderr)
        return outcome.exit_code
    sealed = ""
    if config.report_dir is not None and config.acceptance is not None and (config.report_dir / "summary.json").is_file():
        sealed = seal(config.report_dir, str(config.acceptance["run_id"]))  # the package's manifest, written last
        outcome.reports["manifest"] = config.report_dir / "manifest.json"
    print_final_table(outcome.suite, outcome.cases, Console(), reports=outcome.reports,
                      root_causes=outcome.root_causes)
    if sealed:
        print(f"{_('manifest sha256')}: {sealed}")
    if outcome.exit_code:
        print(f"isight-conformance certify-robot: {outcome.reason}", file=sys.stderr)
    return outcome.exit_code


COMMAND = Command(
    "certify-robot", N_("act as the AI Box and certify a robot (client) implementation against PROTOCOL.md"), add_arguments, main_certify,
    description=N_("Become the AI Box: answer the robot with the reference box's logic, record everything and "
        "judge the robot's frames, session order, stream rate and closes. The first line on stdout is "
        "'listening tcp HOST:PORT udp HOST:PORT'. Exit status: 0 no FAIL/ERROR, 1 FAIL/ERROR, 2 usage error or "
        "no robot connected within --wait. See docs/CERTIFY.md."), lang=True,
)

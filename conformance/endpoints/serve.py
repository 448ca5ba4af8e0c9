"""The ``serve`` command: the reference box in the foreground until SIGINT/SIGTERM (its parser and handler)."""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import signal
import sys
from typing import IO, TYPE_CHECKING, Any

from ..i18n import _
from ..options import add_profile_options, profile_from_options
from ..protocol.answers import SENDABLE_RESULTS
from .behaviour import BoxConfig
from .loop import new_event_loop, run_loop
from .protocols import DEFAULT_MAX_CONNECTIONS
from .server import ReferenceBox

if TYPE_CHECKING:
    from ..options import Subparsers


def raise_fd_limit(wanted: int) -> None:
    """Raise the soft open-files limit towards ``wanted`` (never above the hard limit)."""
    try:
        import resource
    except ImportError:  # pragma: no cover (not POSIX)
        return
    soft, hard = resource.getrlimit(resource.RLIMIT_NOFILE)
    target = wanted if hard == resource.RLIM_INFINITY else min(wanted, hard)
    if soft != resource.RLIM_INFINITY and soft < target:
        with contextlib.suppress(ValueError, OSError):
            resource.setrlimit(resource.RLIMIT_NOFILE, (target, hard))


async def serve(box: ReferenceBox, out: IO[str] = sys.stdout, err: IO[str] = sys.stderr) -> int:
    """Run ``box`` until SIGINT/SIGTERM; print the listening line first. Returns 0."""
    stop = asyncio.Event()
    loop = asyncio.get_running_loop()
    installed = []
    for sig in (signal.SIGINT, signal.SIGTERM):
        with contextlib.suppress(NotImplementedError, RuntimeError, ValueError):
            loop.add_signal_handler(sig, stop.set)
            installed.append(sig)
    try:
        await box.start()
        print(box.describe(), file=out, flush=True)
        await stop.wait()
    finally:
        await box.close()
        for sig in installed:
            loop.remove_signal_handler(sig)
    print(f"isight-conformance serve: stopped; {box.summary()}", file=err, flush=True)
    return 0


def main_serve(
    config: BoxConfig, *, loop: str = "asyncio", out: IO[str] = sys.stdout, err: IO[str] = sys.stderr, **box_kwargs: Any
) -> int:
    """The ``serve`` subcommand: a box in the foreground until SIGINT/SIGTERM."""
    new_event_loop(loop).close()  # fail early and clearly on an unknown/missing loop
    raise_fd_limit(int(box_kwargs.get("max_connections", DEFAULT_MAX_CONNECTIONS)) + 64)
    box = ReferenceBox(config, **box_kwargs)
    return int(run_loop(serve(box, out, err), loop))



__all__ = ["main_serve", "raise_fd_limit", "serve"]


def add_parser(sub: Subparsers) -> argparse.ArgumentParser:
    p = sub.add_parser(
        "serve",
        help=_("run the reference AI Box (TCP and UDP on one port) until SIGINT/SIGTERM"),
        description=_("Run the reference AI Box. The first line on stdout is "
        "'listening tcp HOST:PORT udp HOST:PORT' (useful with --port 0)."),
    )
    net = p.add_argument_group("network")
    net.add_argument("--host", default="127.0.0.1", help=_("address to listen on (default: 127.0.0.1)"))
    net.add_argument("--port", type=int, default=9004, help=_("TCP (and UDP) port; 0 picks a free one (default: 9004)"))
    net.add_argument("--udp-port", type=int, default=None, metavar="PORT",
                     help=_("UDP port, if not the TCP port (0 picks a free one)"))
    net.add_argument("--no-udp", action="store_true", help=_("serve TCP only"))
    net.add_argument("--max-connections", type=int, default=2000, metavar="N",
                     help=_("[R5] at most N TCP connections; past it the stalest is evicted (default: 2000)"))
    net.add_argument("--idle-timeout", type=float, default=300.0, metavar="S",
                     help=_("[R5] close a connection silent for S seconds; 0 = never (default: 300)"))
    net.add_argument("--loop", choices=("asyncio", "uvloop"), default="asyncio",
                     help=_("event loop (uvloop only if installed; default: asyncio)"))
    net.add_argument("--log", metavar="FILE", help=_("append every frame in and out to FILE as JSON lines"))
    knobs = p.add_argument_group("box behaviour")
    knobs.add_argument("--not-ready", action="store_true", help=_("[S2] answer CycleOn with 0001"))
    knobs.add_argument("--cycle-off-fails", action="store_true", help=_("[A3] answer CycleOff with 0002"))
    knobs.add_argument("--latency-ms", type=float, default=0.0, metavar="MS",
                       help=_("[T1] delay every answer by MS milliseconds (default: 0)"))
    knobs.add_argument("--vision-result", type=int, default=1, choices=SENDABLE_RESULTS, metavar="CODE",
                       help=_("[E3] ResultCode answered to a result request: 1, 2, 10, 20, 202, 400 or 409 (default: 1)"))
    knobs.add_argument("--progidx-conflict-box", action="store_true", help=_("[E2] answer ProgIdx with 409"))
    knobs.add_argument("--no-extension", action="store_true",
                       help=_("[E] do not implement actions 26/27 (treated as unknown actions: silence)"))
    knobs.add_argument("--close-on-garbage", action="store_true",
                       help=_("[A5] close a connection that sends bytes that are not a request (default: stay silent)"))
    group = p.add_argument_group("profile")
    add_profile_options(group.add_argument)
    p.set_defaults(func=main_serve_command)
    return p


def main_serve_command(args: argparse.Namespace) -> int:
    config = BoxConfig(
        profile=profile_from_options(args),
        not_ready=args.not_ready,
        cycle_off_fails=args.cycle_off_fails,
        latency_ms=args.latency_ms,
        vision_result=args.vision_result,
        progidx_conflict=args.progidx_conflict_box,
        extension=not args.no_extension,
        on_garbage="close" if args.close_on_garbage else "silent",
    )
    try:
        return main_serve(
            config, loop=args.loop, host=args.host, port=args.port, udp=not args.no_udp, udp_port=args.udp_port,
            max_connections=args.max_connections, idle_timeout=args.idle_timeout, log=args.log,
        )
    except OSError as exc:
        print(f"isight-conformance serve: {exc}", file=sys.stderr)
        return 1

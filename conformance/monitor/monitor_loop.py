"""One monitor run: listen, forward, judge, checkpoint, and write the reports when told to stop.

:func:`run_monitor` listens (TCP, and UDP with ``settings.udp``), prints ``listening tcp
HOST:PORT [udp HOST:PORT] -> upstream HOST:PORT`` as its first line, then runs until
``stop`` is set (SIGINT, SIGTERM and SIGHUP set it in :func:`monitor_main`) or
``duration_s`` has passed. Every ``checkpoint_s`` the reports are written (atomically);
on stop the open connections are closed, the engine judges what is left (a connection
still open is judged as one a capture ends inside), and the final reports are written.
"""

from __future__ import annotations

import asyncio
import contextlib
import signal
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import IO

from ..harness.starvation import gauge, watch_loop
from ..model.verdicts import CaseResult, SuiteInfo
from .hub import Hub, MonitorSettings
from .liveserve import LiveServers
from .monitor_reports import write_monitor_reports
from .proxy import TcpProxy
from .udp_proxy import UdpProxy
from .view import View

__all__ = ["ListenError", "MonitorOutcome", "monitor_main", "run_monitor"]

TICK_S = 0.5


class ListenError(OSError):
    """The monitor cannot listen on --listen."""


@dataclass
class MonitorOutcome:
    hub: Hub
    suite: SuiteInfo
    cases: list[CaseResult]
    checkpoints: int


def _fmt(addr: tuple[str, int]) -> str:
    return f"[{addr[0]}]:{addr[1]}" if ":" in addr[0] else f"{addr[0]}:{addr[1]}"


async def run_monitor(settings: MonitorSettings, report_dir: Path, view: View, stop: asyncio.Event,
                      command: str = "", checkpoint_s: float = 0.0, duration_s: float = 0.0,
                      out: IO[str] = sys.stdout) -> MonitorOutcome:
    hub = Hub(settings, on_finding=view.finding)
    tcp = TcpProxy(hub)
    udp = UdpProxy(hub) if settings.udp else None
    try:
        address = await tcp.start()
        line = f"listening tcp {_fmt(address)}"
        if udp is not None:
            settings.listen = address  # the same port for UDP (--listen :0 picked one)
            line += f" udp {_fmt(await udp.start())}"
    except OSError as exc:
        await tcp.stop()
        raise ListenError(exc.errno, exc.strerror or str(exc)) from None
    settings.listen = address
    print(f"{line} -> upstream {_fmt(settings.upstream)}", file=out, flush=True)
    live = None
    if settings.metrics is not None or settings.http is not None:
        live = LiveServers(hub, report_dir, settings.metrics, settings.http)
        try:
            got = await live.start()
        except OSError as exc:
            await tcp.stop()
            if udp is not None:
                await udp.stop()
            raise ListenError(exc.errno, f"--metrics/--http: {exc.strerror or exc}") from None
        if "metrics" in got:
            settings.metrics = got["metrics"]
            print(f"metrics http://{_fmt(got['metrics'])}/metrics", file=out, flush=True)
        if "http" in got:
            settings.http = got["http"]
            print(f"page http://{_fmt(got['http'])}/", file=out, flush=True)
    view.start(hub)
    gauge().start()  # the monitor's own stalls: a T2 breach they could explain is INCONCLUSIVE (analyze.timing)
    loop = asyncio.get_running_loop()
    stop_watch = watch_loop(loop)
    end = loop.time() + duration_s if duration_s else None
    next_checkpoint = loop.time() + checkpoint_s if checkpoint_s else None
    checkpoints = 0
    try:
        while not stop.is_set():
            with contextlib.suppress(asyncio.TimeoutError, TimeoutError):
                await asyncio.wait_for(stop.wait(), TICK_S)
            now = loop.time()
            if end is not None and now >= end:
                break
            hub.tick()
            view.tick()
            if live is not None:
                live.tick()
            if next_checkpoint is not None and now >= next_checkpoint:
                next_checkpoint = now + checkpoint_s
                try:
                    write_monitor_reports(hub, report_dir, command, settings.acceptance)
                    checkpoints += 1
                except OSError as exc:  # a full disk at a checkpoint: the line goes on, the next one retries
                    hub.note(f"checkpoint: cannot write the reports: {exc.strerror or exc}")
                    view.line(f"isight-conformance monitor: checkpoint: cannot write the reports: {exc.strerror or exc}")
    finally:
        view.stop()
        if live is not None:
            await live.stop()
        await tcp.stop()
        if udp is not None:
            await udp.stop()
        hub.finish()
        stop_watch()
        gauge().stop()
    suite, cases = write_monitor_reports(hub, report_dir, command, settings.acceptance)
    return MonitorOutcome(hub, suite, cases, checkpoints)


def monitor_main(settings: MonitorSettings, report_dir: Path, view: View, command: str = "",
                 checkpoint_s: float = 0.0, duration_s: float = 0.0) -> MonitorOutcome:
    """Run until SIGINT, SIGTERM or SIGHUP (or ``duration_s``); the reports are written either way."""

    async def main() -> MonitorOutcome:
        stop = asyncio.Event()
        loop = asyncio.get_running_loop()
        for sig in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP):
            with contextlib.suppress(NotImplementedError, ValueError, RuntimeError):
                loop.add_signal_handler(sig, stop.set)
        return await run_monitor(settings, report_dir, view, stop, command, checkpoint_s, duration_s)

    return asyncio.run(main())

"""Running the monitor in-process for the tests: ``async with monitored(box_port, tmp_path) as m``.

The monitor runs in the test's event loop (a task), listening on a free loopback port
(``m.port``); leaving the block stops it as a signal would and leaves the outcome in
``m.outcome`` (hub, suite, cases) and the reports in ``m.report_dir``.
"""

from __future__ import annotations

import asyncio
import io
import json
import struct
import time
from collections.abc import AsyncIterator
from contextlib import asynccontextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from conformance.analyze.analysis_context import AnalyzeConfig
from conformance.monitor.hub import MonitorSettings
from conformance.monitor.monitor_loop import MonitorOutcome, run_monitor
from conformance.monitor.view import View
from conformance.protocol import DEFAULT_PROFILE, Profile


@dataclass
class Monitored:
    settings: MonitorSettings
    report_dir: Path
    view_out: io.StringIO
    outcome: MonitorOutcome | None = None
    stop: asyncio.Event = field(default_factory=asyncio.Event)
    view: View | None = None

    async def settled(self, timeout: float = 10.0) -> None:
        """Until every connection through the monitor has closed on both sides (bounded)."""
        for _ in range(int(timeout / 0.01)):
            hub = self.view.hub if self.view is not None else None
            if hub is not None and not hub.open:
                return
            await asyncio.sleep(0.01)

    @property
    def port(self) -> int:
        return self.settings.listen[1]

    @property
    def target(self) -> tuple[str, int]:
        return ("127.0.0.1", self.port)

    def summary(self) -> dict[str, Any]:
        return json.loads((self.report_dir / "summary.json").read_text())

    def verdicts(self) -> dict[str, str]:
        return {c["id"]: c["verdict"] for c in self.summary()["cases"]}

    def failing(self) -> dict[str, str]:
        return {k: v for k, v in self.verdicts().items() if v in ("FAIL", "NON-STRICT", "ERROR")}

    def monitor_json(self) -> dict[str, Any]:
        return json.loads((self.report_dir / "monitor.json").read_text())


@asynccontextmanager
async def monitored(box_port: int, tmp_path: Path, faults: list[str] | tuple[str, ...] = (),
                    profile: Profile = DEFAULT_PROFILE, pcaps: bool = True, udp: bool = False,
                    connect_timeout_s: float = 5.0, tty: bool = False, **ring: Any) -> AsyncIterator[Monitored]:
    config = AnalyzeConfig(profile=profile, ports=(box_port,), heuristic=False)
    settings = MonitorSettings(("127.0.0.1", 0), ("127.0.0.1", box_port), config,
                               tmp_path / "pcaps" if pcaps else None, faults=list(faults), udp=udp,
                               connect_timeout_s=connect_timeout_s, **ring)
    m = Monitored(settings, tmp_path / "report", io.StringIO())
    view = m.view = View(m.view_out, tty=tty)
    task = asyncio.ensure_future(run_monitor(settings, m.report_dir, view, m.stop, out=io.StringIO()))
    deadline = time.monotonic() + 20  # bounded; a loaded runner may take seconds to bind
    while time.monotonic() < deadline:  # the monitor sets settings.listen (.http, .metrics) to the addresses it got
        bound = [settings.listen] + [a for a in (settings.http, settings.metrics) if a is not None]
        if all(address[1] for address in bound) or task.done():
            break
        await asyncio.sleep(0.01)
    if task.done():
        task.result()  # raises the monitor's error
    try:
        yield m
    finally:
        m.stop.set()
        m.outcome = await asyncio.wait_for(task, 60)


def pcapng_comments(path: Path) -> list[tuple[int, str]]:
    """(packet number from 1, comment) of every Enhanced Packet Block's comments, parsed block by block."""
    data = path.read_bytes()
    out: list[tuple[int, str]] = []
    at, packet = 0, 0
    while at + 12 <= len(data):
        kind, total = struct.unpack_from("<II", data, at)
        if total < 12 or at + total > len(data):
            raise ValueError(f"{path}: a block cut short at byte {at}")
        if kind == 6:
            packet += 1
            caplen = struct.unpack_from("<I", data, at + 20)[0]
            opt = at + 28 + caplen + (-caplen % 4)
            while opt + 4 <= at + total - 4:
                code, length = struct.unpack_from("<HH", data, opt)
                if code == 0:
                    break
                if code == 1:
                    out.append((packet, data[opt + 4 : opt + 4 + length].decode("utf-8", "replace")))
                opt += 4 + length + (-length % 4)
        at += total
    return out

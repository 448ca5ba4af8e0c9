"""What the monitor shows while it runs.

Every finding prints as it is filed, one line naming the side at fault, its clause and
verdict, and the frame numbers (the first :data:`SHOWN` of each root cause, then each
time its count reaches a power of ten, so a flood of one defect stays readable). On a
terminal a live panel (rich) shows connections, sessions completed, frames each way,
the latency of the answers (p50/p99), the pose stream's rate and the root causes so
far; without one, a status line every :data:`STATUS_EVERY_S` seconds.

The counts are the engine's (each connection's :class:`~conformance.analyze.exchanges.ConnJudge`:
requests, poses, answers; :meth:`~.hub.Hub.counts`).
"""

from __future__ import annotations

import math
import time
from typing import IO, Any

from ..analyze.findings import Observation
from ..i18n import _
from ..model.percentiles import percentile
from .alarms import Alarm
from .hub import Hub
from .live_findings import Cause

__all__ = ["STATUS_EVERY_S", "View"]

SHOWN = 3
STATUS_EVERY_S = 60.0


class Counts:
    """Frames each way and poses so far, and the pose stream's rate (poses per second since the last look)."""

    def __init__(self) -> None:
        self.last_poses = 0
        self.last_t = time.monotonic()
        self.rate = 0.0

    def update(self, hub: Hub) -> tuple[int, int, int, list[float]]:
        requests, answers, poses = hub.counts()
        recent: list[float] = []
        for conn in hub.open.values():
            if conn.judge is not None:
                recent.extend(conn.judge._latencies[-200:])
        t = time.monotonic()
        if t - self.last_t >= 1.0:
            self.rate = (poses - self.last_poses) / (t - self.last_t)
            self.last_poses, self.last_t = poses, t
        return requests, answers, poses, recent


def _ms(v: float) -> str:
    return "-" if math.isnan(v) else f"{v:.2f}"


class View:
    def __init__(self, out: IO[str], tty: bool, quiet: bool = False) -> None:
        self.out = out
        self.tty = tty
        self.quiet = quiet
        self.counts = Counts()
        self.live: Any = None
        self.hub: Hub | None = None
        self.last_status = time.monotonic()

    # -- findings -----------------------------------------------------------------------------------
    def finding(self, clause: str, side: str, finding: Observation, cause: Cause) -> None:
        n = cause.count
        if n > SHOWN and not (n >= 10 and math.log10(n).is_integer()):
            return
        more = " " + _("[{n}× so far]").format(n=f"{n:,}") if n > SHOWN else ""
        self.line(f"{time.strftime('%H:%M:%S')} {finding.verdict.value} {side.upper()} {clause}: "
                  f"{finding.line()}{more}")

    def alarm(self, alarm: Alarm) -> None:
        """An alarm raised or cleared (printed even with --quiet: it is a finding as it happens)."""
        if alarm.active:
            self.line(f"{time.strftime('%H:%M:%S')} ALARM {alarm.line()}")
        else:
            self.line(f"{time.strftime('%H:%M:%S')} " + _("CLEARED") + f" #{alarm.id} {alarm.line()}")

    def line(self, text: str) -> None:
        if self.live is not None:
            self.live.console.print(text, markup=False, highlight=False, soft_wrap=True)
        else:
            print(text, file=self.out, flush=True)

    # -- status -------------------------------------------------------------------------------------
    def status(self, hub: Hub) -> str:
        requests, answers, poses, recent = self.counts.update(hub)
        lat = hub.ctx.latency
        pose = _("pose latency p50 {p50} p99 {p99} ms; ").format(
            p50=_ms(percentile(recent, 50)), p99=_ms(percentile(recent, 99))) if recent else ""
        bad = sum(c.count for c in hub.findings.roots.causes.values())
        return time.strftime('%H:%M:%S') + " " + _(
            "status: {open} open / {connections} connection(s), {sessions} session(s) done, frames robot→box "
            "{requests} box→robot {answers}, answer latency p50 {p50} p99 {p99} ms; {pose}stream {rate} poses/s; "
            "findings {findings} in {causes} root cause(s); injected {injected}").format(
            open=len(hub.open), connections=f"{hub.connections:,}", sessions=f"{hub.ctx.stats.sessions:,}",
            requests=f"{requests:,}", answers=f"{answers:,}", p50=_ms(lat.percentile(50)),
            p99=_ms(lat.percentile(99)), pose=pose, rate=f"{self.counts.rate:.1f}", findings=f"{bad:,}",
            causes=len(hub.findings.roots.causes), injected=f"{hub.reactions.total:,}") + "; " + _(
            "alarms {alarms} active").format(alarms=len(hub.alarms.active))

    def _panel(self, hub: Hub) -> Any:
        from rich.table import Table

        requests, answers, poses, recent = self.counts.update(hub)
        lat = hub.ctx.latency
        s = hub.settings
        t = Table(title=f"isight-conformance monitor {s.listen[0]}:{s.listen[1]} → {s.upstream[0]}:{s.upstream[1]}"
                        f" ({hub.elapsed():.0f} s)", show_header=False, expand=False)
        t.add_column(style="bold")
        t.add_column()
        t.add_row(_("connections"), _("{open} open, {all} in all, {refused} the box did not accept").format(
            open=len(hub.open), all=f"{hub.connections:,}", refused=hub.upstream_failures))
        t.add_row(_("sessions completed"), f"{hub.ctx.stats.sessions:,}")
        t.add_row(_("frames"), _("robot → box {requests}, box → robot {answers} ({packets} packets)").format(
            requests=f"{requests:,}", answers=f"{answers:,}", packets=f"{hub.wire.frames:,}"))
        latency = _("p50 {p50} ms, p99 {p99} ms").format(p50=_ms(lat.percentile(50)), p99=_ms(lat.percentile(99)))
        if recent:
            latency += _("; poses p50 {p50}, p99 {p99} ms").format(p50=_ms(percentile(recent, 50)),
                                                                  p99=_ms(percentile(recent, 99)))
        t.add_row(_("answer latency"), latency)
        t.add_row(_("pose stream"), _("{rate} poses/s ({poses} in all)").format(rate=f"{self.counts.rate:.1f}",
                                                                               poses=f"{poses:,}"))
        t.add_row(_("faults injected"), f"{hub.reactions.total:,}")
        active = sorted(hub.alarms.active.values(), key=lambda a: a.raised)
        t.add_row(_("alarms"), f"{len(active)} " + _("active") if active else _("none"))
        for a in active[:5]:
            t.add_row(f"  ALARM {a.side} {a.clause}", a.text[:110])
        causes = hub.findings.roots.ordered()
        t.add_row(_("root causes"), f"{len(causes)}" if causes else _("none so far"))
        for c in causes[:8]:
            t.add_row(f"  {c.verdict.value} {c.side} {c.clause}", f"{c.count:,}× {c.signature}"[:110])
        return t

    def start(self, hub: Hub) -> None:
        self.hub = hub
        if self.tty and not self.quiet:
            from rich.console import Console
            from rich.live import Live

            self.live = Live(self._panel(hub), console=Console(file=self.out), refresh_per_second=2,
                             transient=False)
            self.live.start()

    def tick(self) -> None:
        """About twice a second."""
        hub = self.hub
        if hub is None:
            return
        for alarm in hub.alarms.take_changes():
            self.alarm(alarm)
        if self.live is not None:
            self.live.update(self._panel(hub))
        elif time.monotonic() - self.last_status >= STATUS_EVERY_S:
            self.last_status = time.monotonic()
            if not self.quiet:
                self.line(self.status(hub))

    def stop(self) -> None:
        if self.live is not None:
            self.live.stop()
            self.live = None

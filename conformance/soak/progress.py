"""The soak's live progress line (rich, on a terminal) and its one line per window (in a log)."""

from __future__ import annotations

import math
import sys
from typing import Any

from rich.console import Console
from rich.live import Live
from rich.text import Text

from ..report.summary import format_duration
from .windows import WindowRow


def _ms(value: Any) -> str:
    return "–" if value is None or (isinstance(value, float) and math.isnan(value)) else f"{float(value):.2f} ms"


def progress_text(elapsed_s: float, duration_s: float, sessions: int, failed: int, p99: Any,
                  resources: dict[str, Any] | None, events: int) -> str:
    share = min(100.0, 100.0 * elapsed_s / duration_s) if duration_s else 0.0
    line = (f"soak {format_duration(elapsed_s)} of {format_duration(duration_s)} ({share:.0f} %) · "
            f"{sessions:,} sessions · {failed} failed · p99 {_ms(p99)} · {events} events")
    if resources and resources.get("rss_mb") is not None:
        line += f" · box RSS {resources['rss_mb']:.1f} MB, {resources.get('fds') or 0:.0f} fds"
    return line


def window_line(row: WindowRow) -> str:
    lat = row.latency
    text = (f"window {row.index} [{row.start_s:.0f}–{row.end_s:.0f} s]: {row.sessions_ok} ok, "
            f"{row.sessions_failed} failed, p50 {_ms(lat.get('p50'))}, p99 {_ms(lat.get('p99'))}, "
            f"max {_ms(lat.get('max'))}, missing {row.answers_missing}")
    res = row.resources
    if res.get("rss_mb") is not None:
        text += f", box RSS {res['rss_mb']:.1f} MB, fds {res.get('fds') or 0:.0f}, threads {res.get('threads') or 0:.0f}"
    return text


class Progress:
    """A live line on a terminal (redrawn every second); one line per window otherwise; nothing when quiet."""

    def __init__(self, duration_s: float, quiet: bool) -> None:
        self.duration_s = duration_s
        self.quiet = quiet
        self.console = Console(file=sys.stderr)
        self.live: Live | None = None
        if not quiet and self.console.is_terminal:
            self.live = Live(Text(""), console=self.console, refresh_per_second=2, transient=True)

    def __enter__(self) -> Progress:
        if self.live is not None:
            self.live.start()
        return self

    def __exit__(self, *exc: object) -> None:
        if self.live is not None:
            self.live.stop()

    def tick(self, player: Any) -> None:
        if self.live is None:
            return
        rows = player.rows
        last = rows[-1] if rows else None
        p99 = last.latency.get("p99") if last else player.window.latency.quantile(99)
        sessions = player.served + player.failed
        self.live.update(Text(progress_text(player.elapsed(), self.duration_s, sessions, player.failed, p99,
                                            last.resources if last else None, sum(player.events.values()))))

    def window(self, row: WindowRow) -> None:
        if self.quiet:
            return
        if self.live is not None:
            self.live.console.print(window_line(row), highlight=False)
        else:
            print(window_line(row), file=sys.stderr, flush=True)


__all__ = ["Progress", "progress_text", "window_line"]

"""What a soak is asked to do: :class:`SoakSettings`, and the event plan (:class:`EventPlan`).

``--events RATE`` plants events at a rate: ``6/h`` or ``1/min`` (events per hour or minute of
the soak, spread at random, the seed's), or a share of sessions, ``0.1`` (one session in ten).
The kinds take turns (``--event-kinds``), so a short soak sees each of them.
"""

from __future__ import annotations

import random
from dataclasses import dataclass, field
from pathlib import Path

from ..harness.target import Target
from ..protocol import DEFAULT_PROFILE, Profile
from .duration import parse_span

EVENT_KINDS: tuple[str, ...] = ("vanish", "reset", "stall", "burst")


@dataclass(frozen=True)
class EventRate:
    """Events per second of soak, or a share of sessions (one of the two, or neither: no events)."""

    per_s: float = 0.0
    share: float = 0.0

    @property
    def any(self) -> bool:
        return self.per_s > 0 or self.share > 0

    def __str__(self) -> str:
        if self.per_s:
            return f"{self.per_s * 3600:g}/h"
        return f"{self.share:g} of sessions" if self.share else "none"


def parse_events(text: str) -> EventRate:
    """``6/h``, ``1/min``, ``30/d``, ``0.1`` (a share of sessions), ``0``/``off``; ValueError otherwise."""
    raw = text.strip().lower()
    if raw in ("0", "off", "none", ""):
        return EventRate()
    if "/" in raw:
        count, _, unit = raw.partition("/")
        per = {"s": 1.0, "min": 60.0, "m": 60.0, "h": 3600.0, "d": 86400.0}.get(unit.strip())
        try:
            number = float(count)
        except ValueError:
            number = -1.0
        if per is None or not 0 < number <= 3600 * per:
            raise ValueError(f"--events: {text!r} is not a rate; expected N/h, N/min or a share of sessions such as 0.1")
        return EventRate(per_s=number / per)
    try:
        share = float(raw)
    except ValueError:
        raise ValueError(f"--events: {text!r} is not a rate; expected N/h, N/min or a share of sessions "
                         "such as 0.1") from None
    if not 0 <= share <= 1:
        raise ValueError(f"--events: a share of sessions is 0 to 1, not {text!r}")
    return EventRate(share=share)


def parse_kinds(text: str) -> tuple[str, ...]:
    kinds = tuple(k.strip() for k in text.split(",") if k.strip())
    unknown = [k for k in kinds if k not in EVENT_KINDS]
    if unknown or not kinds:
        raise ValueError(f"--event-kinds: unknown {', '.join(unknown) or 'empty list'}; known: {', '.join(EVENT_KINDS)}")
    return kinds


@dataclass(frozen=True)
class SoakSettings:
    duration_s: float
    target: Target | None = None
    window_s: float = 60.0
    robots: int = 1
    cycle_s: float = 5.0
    events: EventRate = field(default_factory=EventRate)
    event_kinds: tuple[str, ...] = EVENT_KINDS
    stall_s: float = 3.0
    burst_size: int = 10
    ghost_hold_s: float = 120.0
    box_pid: int | None = None
    restart_cmd: str | None = None
    report_dir: Path | None = None
    seed: int = 0
    profile: Profile = DEFAULT_PROFILE
    extension: str = "auto"
    quiet: bool = False
    #: keep the live pcaps of the newest N windows (and of every window with a finding); 0: no pcaps
    pcap_ring: int = 0
    pcap_interface: str = "lo"
    #: stop early when every session failed for this many windows in a row (the box stopped serving)
    stop_after_dead_windows: int = 3

    def __post_init__(self) -> None:
        if not 1 <= self.robots <= 64:
            raise ValueError(f"--robots: 1 to 64, not {self.robots}")
        if not 0.1 <= self.cycle_s <= 3600:
            raise ValueError(f"--cycle-s: 0.1 to 3600 seconds, not {self.cycle_s:g}")
        if self.window_s > self.duration_s:
            raise ValueError(f"--window ({self.window_s:g} s) is longer than --duration ({self.duration_s:g} s)")
        if not 0 <= self.stall_s <= 600:
            raise ValueError(f"--stall-s: 0 to 600 seconds, not {self.stall_s:g}")
        if not 1 <= self.burst_size <= 500:
            raise ValueError(f"--burst: 1 to 500 connections, not {self.burst_size}")
        if not 0 <= self.pcap_ring <= 10_000:
            raise ValueError(f"--pcap-ring: 0 to 10000 windows, not {self.pcap_ring}")
        if self.ghost_hold_s < 0:
            raise ValueError("--ghost-hold: not negative")
        if self.box_pid is not None and self.restart_cmd is not None:
            raise ValueError("--box-pid and --restart-cmd: one or the other (the box --restart-cmd starts is watched)")

    @property
    def time_out_ms(self) -> float:
        return float(self.profile.time_out_ms)


def default_window(duration_s: float) -> float:
    """A minute; a tenth of a soak shorter than ten minutes (so that a trend has its windows), at least 1 s."""
    return 60.0 if duration_s >= 600 else max(1.0, round(duration_s / 10, 1))


def parse_window(text: str) -> float:
    return parse_span(text, "--window", shortest_s=0.2)


class EventPlan:
    """Which planted event the next session carries ("" for none), from the rate and the seed."""

    def __init__(self, rate: EventRate, kinds: tuple[str, ...], seed: int) -> None:
        self.rate = rate
        self.kinds = kinds
        self.rng = random.Random(seed)
        self.turn = 0
        self.due = self.rng.expovariate(rate.per_s) if rate.per_s else float("inf")

    def _kind(self) -> str:
        kind = self.kinds[self.turn % len(self.kinds)]
        self.turn += 1
        return kind

    def next(self, now_s: float) -> str:
        if self.rate.share and self.rng.random() < self.rate.share:
            return self._kind()
        if self.rate.per_s and now_s >= self.due:
            self.due = max(self.due, now_s) + self.rng.expovariate(self.rate.per_s)
            return self._kind()
        return ""

    def where(self) -> float:
        """How far into the cycle the event strikes (a fraction of the trajectory)."""
        return self.rng.uniform(0.25, 0.75)


__all__ = ["EVENT_KINDS", "EventPlan", "EventRate", "SoakSettings", "default_window", "parse_events", "parse_kinds",
           "parse_window"]

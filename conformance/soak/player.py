"""The soak's event loop: robots playing sessions back to back, planted events, windows closing.

``await SoakPlayer(settings, target, extension, probe, on_window).run(stop)`` plays until the
duration is over, ``stop`` is set (SIGINT/SIGTERM), the box's process ends, or the box has
served nothing for :attr:`~.settings.SoakSettings.stop_after_dead_windows` windows. Each window
closes into a row; ``on_window(row)`` runs in a worker thread (the checkpoint) before the
next one closes. Nothing per frame outlives its session.
"""

from __future__ import annotations

import asyncio
import contextlib
import time
from collections import Counter
from collections.abc import Callable

from ..harness.starvation import gauge
from .resources import BoxGone, BoxProbe, own_rss_mb
from .sessions import Ghosts, SoakSession, reconnect_burst
from .settings import EventPlan, SoakSettings
from .verdicts import Stopped
from .windows import SessionOutcome, Window, WindowRow

perf = time.perf_counter
#: after a failed session a robot waits this long (at most) before the next: a dead box is not hammered
BACKOFF_S = 1.0
#: E4 sessions all answered ProgIdx 409 (not ready) before the soak falls back to S1 sessions
FALLBACK_AFTER = 3
#: a streak of failed sessions this long (or one per robot, if more) at the end is "stopped serving"
STREAK_MIN = 3


class SoakPlayer:
    def __init__(self, settings: SoakSettings, target: tuple[str, int], extension: bool, probe: BoxProbe | None,
                 on_window: Callable[[WindowRow], None] | None = None,
                 progress: Callable[[SoakPlayer], None] | None = None) -> None:
        self.settings = settings
        self.target = target
        self.extension = extension
        self.probe = probe
        self.on_window = on_window
        self.progress = progress
        self.rows: list[WindowRow] = []
        self.window = Window(0, 0.0, settings.time_out_ms)
        self.plan = EventPlan(settings.events, settings.event_kinds, settings.seed)
        self.ghosts = Ghosts(settings.ghost_hold_s)
        self.t0 = 0.0
        self.served = 0  # sessions served whole (ok)
        self.judged = 0  # sessions judged (ok or failed) in closed windows
        self.failed = 0
        self.events: Counter[str] = Counter()
        self.streak = 0
        self.streak_from = 0
        self.streak_at = 0.0
        self.streak_kind = ""
        self.streak_reason = ""
        self.streak_half_open = 0
        self.box_gone: str | None = None
        self.box_gone_at = 0.0
        self.ended_by = "duration"
        self.dead_windows = 0
        self.soak_rss: list[float] = []  # the soak's own RSS, one per window (bounded by the windows)
        self._done = asyncio.Event()
        self.closing = False  # the duration is over: robots start no new session
        self.conflicts = 0  # E4 sessions whose ProgIdx was answered 409 (not ready) before any was served
        self.notes: list[str] = []
        self.releasing: Stopped | None = None  # the soak reset the abandoned connections of a box that stopped
        self.half_open_outages: list[Stopped] = []  # stops that ended once the abandoned connections were reset

    # -- what the reports read ------------------------------------------------------------------------
    def elapsed(self) -> float:
        return perf() - self.t0 if self.t0 else 0.0

    def stopped(self) -> Stopped | None:
        """The box stopped serving (its process ended, or every session failed to the end), else None (also
        when the soak ended while it tested a box that abandoned connections had stopped before: R5 says it)."""
        if self.box_gone is None and self.releasing is not None and self.half_open_outages:
            return None
        if self.box_gone is not None:
            return Stopped(self.served, self.box_gone_at, "died", self.box_gone, self.streak_half_open)
        if self.streak >= max(STREAK_MIN, self.settings.robots) and self.dead_windows:
            return Stopped(self.streak_from, self.streak_at, self.streak_kind, self.streak_reason,
                           self.streak_half_open)
        return None

    # -- running ------------------------------------------------------------------------------------
    async def run(self, stop: asyncio.Event) -> None:
        self.t0 = perf()
        tasks = [asyncio.create_task(self._robot(i)) for i in range(self.settings.robots)]
        ticker = asyncio.create_task(self._ticker())
        helpers = [ticker]
        if self.progress is not None:
            helpers.append(asyncio.create_task(self._progress()))
        waiters = [asyncio.create_task(stop.wait()), asyncio.create_task(self._done.wait())]
        with gauge():
            await asyncio.wait(waiters, timeout=self.settings.duration_s, return_when=asyncio.FIRST_COMPLETED)
            if stop.is_set():
                self.ended_by = "signal"
            elif not self._done.is_set():
                # the duration is over: no new session starts, the ones under way finish (a bounded grace)
                self.closing = True
                finishing = asyncio.create_task(asyncio.wait(tasks, timeout=self._grace_s()))
                await asyncio.wait([finishing, waiters[0]], return_when=asyncio.FIRST_COMPLETED)
                finishing.cancel()
                if stop.is_set():
                    self.ended_by = "signal"
            for task in [*tasks, *waiters]:
                task.cancel()
            await asyncio.gather(*tasks, *waiters, return_exceptions=True)
            ticker.cancel()
            await asyncio.gather(ticker, return_exceptions=True)
            if self.window.ok + self.window.failed + self.window.cut or not self.rows:
                await self._close_window(perf())  # the last, partial window keeps what it saw
        for task in helpers[1:]:
            task.cancel()
        await asyncio.gather(*helpers[1:], return_exceptions=True)
        self.ghosts.release_all()

    def _grace_s(self) -> float:
        """How long the sessions under way at the end may take to finish: a whole session's bounds."""
        settings = self.settings
        return settings.cycle_s + settings.stall_s + 1.0 + 4 * settings.profile.time_out_s

    async def _progress(self) -> None:
        assert self.progress is not None
        while True:
            self.progress(self)
            await asyncio.sleep(1.0)

    async def _robot(self, robot: int) -> None:
        settings = self.settings
        after = ""
        clear = False
        while not self.closing:
            # no event while the soak tests whether abandoned connections stopped the box: a clean experiment
            event = self.plan.next(self.elapsed()) if self.releasing is None else ""
            if event:
                self.events[event] += 1
                self.window.note_event(event)
            if event == "burst":
                self._add(await reconnect_burst(self.target, settings.profile, robot, settings.burst_size))
                event = ""
            session = SoakSession(
                self.target, settings.profile, robot=robot, duration=settings.cycle_s, extension=self.extension,
                event=event, event_at=self.plan.where(), stall_s=settings.stall_s, after_event=after,
                ghosts=self.ghosts, result_wait=min(1.0, settings.cycle_s), shared=settings.robots > 1,
                clear_cycle=clear,
            )
            await session.run()
            outcome = session.outcome(settings.time_out_ms)
            del session
            self._add(outcome)
            after = event if event in ("vanish", "reset") else ""
            clear = bool(after) or outcome.failure == "not-ready"
            if not outcome.ok and not self.closing:  # a robot told "not ready" waits before it tries again too
                await asyncio.sleep(min(BACKOFF_S, settings.cycle_s))

    def _add(self, outcome: SessionOutcome) -> None:
        self.window.add(outcome)
        if outcome.prog_idx_conflict and not self.served and self.extension:
            self.conflicts += 1
            if self.conflicts >= FALLBACK_AFTER:
                self.extension = False  # the next sessions are S1: a soak of E4 sessions would judge nothing
                self.notes.append(f"ProgIdx was answered 409 (not ready, E2) in the first {self.conflicts} E4 "
                                  "sessions: the soak plays S1 sessions instead")
        if outcome.event in ("vanish", "reset"):
            return
        if outcome.ok:
            self.served += 1
            self.streak = 0
        elif outcome.failure != "not-ready":
            self.failed += 1
            if not self.streak:
                self.streak_from, self.streak_at = self.served, self.elapsed()
                self.streak_kind, self.streak_reason = outcome.failure, outcome.reason
                self.streak_half_open = len(self.ghosts.ring)
            self.streak += 1

    async def _ticker(self) -> None:
        window_s = self.settings.window_s
        while True:
            due = self.t0 + (self.window.index + 1) * window_s
            await asyncio.sleep(max(0.0, due - perf()))
            await self._close_window(due)

    def _sample(self) -> dict[str, float | None]:
        resources: dict[str, float | None] = {}
        if self.probe is not None and self.box_gone is None:
            try:
                resources = self.probe.sample(self.ghosts.ports())
            except BoxGone as gone:
                self.box_gone, self.box_gone_at = str(gone), self.elapsed()
        rss = own_rss_mb()
        self.soak_rss.append(round(rss, 3))
        resources["soak_rss_mb"] = round(rss, 3)
        resources["half_open_abandoned"] = float(len(self.ghosts.ring))
        return resources

    def _test_half_open(self, row: WindowRow) -> None:
        """Did the abandoned connections stop the box? When it serves nothing for a window while the soak
        holds some, the soak resets them all; serving again in the next windows says they held it (R5)."""
        if self.dead_windows == 1 and self.ghosts.ring:
            self.releasing = Stopped(self.streak_from, self.streak_at, self.streak_kind, self.streak_reason,
                                     len(self.ghosts.ring))
            self.ghosts.release_all()
            self.notes.append(f"window {row.index}: nothing served with {self.releasing.half_open} abandoned "
                              "connections open; the soak reset them all to see whether they held the box")
        elif self.releasing is not None and row.sessions_ok:
            self.half_open_outages.append(self.releasing)
            self.notes.append(f"window {row.index}: the box served again once its {self.releasing.half_open} "
                              "abandoned connections were reset: they held it (R5)")
            self.releasing = None
        elif self.releasing is not None and self.dead_windows >= self.settings.stop_after_dead_windows:
            self.notes.append(f"resetting the {self.releasing.half_open} abandoned connections did not bring the "
                              "box back")
            self.releasing = None

    async def _close_window(self, end: float) -> None:
        loop = asyncio.get_running_loop()
        self.ghosts.sweep()
        resources = await loop.run_in_executor(None, self._sample)
        window = self.window
        stall = gauge().worst_ms(self.t0 + window.start_s, end)
        row = window.close(end - self.t0, self.judged, resources, stall)
        self.judged = row.sessions_total
        self.rows.append(row)
        self.window = Window(window.index + 1, end - self.t0, self.settings.time_out_ms)
        dead = row.sessions_ok == 0 and self.streak > 0  # nothing served, and the last session failed
        self.dead_windows = self.dead_windows + 1 if dead else 0
        self._test_half_open(row)
        if self.box_gone is not None:
            self.ended_by = "box died"
            self._done.set()
        elif self.dead_windows >= self.settings.stop_after_dead_windows:
            self.ended_by = "stopped serving"
            self._done.set()
        if self.on_window is not None:
            with contextlib.suppress(Exception):
                await loop.run_in_executor(None, self.on_window, row)


__all__ = ["BACKOFF_S", "STREAK_MIN", "SoakPlayer"]

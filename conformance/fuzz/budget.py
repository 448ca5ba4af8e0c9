"""A campaign's budget, shared between frame cases and sessions from the first second.

With ``duration_s`` the sessions get ``stateful_share`` of the time, all along: the
campaign asks :meth:`Budget.next_part` between chunks, which picks the part that is
behind its share (sessions first, so state is fuzzed from the first second). With
``max_examples`` the frames get ``max_examples × (1 - share)`` cases and the sessions
``max_examples × share`` steps (at least one of each when the share is strictly between 0 and 1).
"""

from __future__ import annotations

import time
from collections.abc import Iterator
from contextlib import contextmanager

from .config import CampaignConfig


class Budget:
    def __init__(self, config: CampaignConfig) -> None:
        self.config = config
        self.started = time.monotonic()
        self.spent = {"frames": 0.0, "sessions": 0.0}  # seconds in each part

    @property
    def frames_budget(self) -> int | None:
        cfg = self.config
        if cfg.max_examples is None:
            return None
        frames = round(cfg.max_examples * (1 - cfg.stateful_share))
        return frames if cfg.stateful_share >= 1 else max(1, frames)

    @property
    def steps_budget(self) -> int | None:
        cfg = self.config
        if cfg.max_examples is None or cfg.stateful_share <= 0:
            return None if cfg.stateful_share > 0 else 0
        return max(1, cfg.max_examples - (self.frames_budget or 0))

    def elapsed(self) -> float:
        return time.monotonic() - self.started

    def time_left(self) -> bool:
        d = self.config.duration_s
        return d is None or self.elapsed() < d

    def frames_left(self, examples: int) -> bool:
        if self.config.stateful_share >= 1:
            return False
        budget = self.frames_budget
        return (budget is None or examples < budget) and self.time_left()

    def sessions_left(self, steps: int) -> bool:
        if self.config.stateful_share <= 0:
            return False
        budget = self.steps_budget
        return (budget is None or steps < budget) and self.time_left()

    def next_part(self, examples: int, steps: int, sessions_possible: bool = True) -> str | None:
        """"frames", "sessions" or None (both spent): the part behind its share goes next."""
        frames = self.frames_left(examples)
        sessions = sessions_possible and self.sessions_left(steps)
        if frames and sessions:
            share = self.config.stateful_share
            if self.config.duration_s is not None:
                total = self.spent["frames"] + self.spent["sessions"]
                now = self.spent["sessions"] / total if total else 0.0
            else:
                now = steps / max(1, steps + examples)
            return "sessions" if now <= share else "frames"
        return "frames" if frames else "sessions" if sessions else None

    @contextmanager
    def timing(self, part: str) -> Iterator[None]:
        start = time.monotonic()
        try:
            yield
        finally:
            self.spent[part] += time.monotonic() - start


__all__ = ["Budget"]

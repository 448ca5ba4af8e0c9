"""How long ``certify-robot`` takes to answer, like a real AI Box: a box takes time to start and
stop a detection, so CycleOn, CycleOff and the result request (27) are answered after a latency
drawn from a legal range (a few hundred ms, inside time_out), seeded so that a run repeats.

A robot that does not wait for an answer (CycleOff 1 ms after CycleOn) passes against a box that
answers in under a millisecond; against these latencies its next request comes before the answer
and RB-A1-01 (A1/T1) FAILs with the frames. ``--answer-latency 0`` answers at once.

The answers of one connection stay in order: an answer goes out ``delay`` after its request
arrived, or right after the answer before it, whichever is later (so every answer still leaves
within the range's top after its request). Datagrams (UDP) are answered at once.
"""

from __future__ import annotations

import random

from ..protocol import Action, Profile

#: the requests a real box takes time to answer (starting and stopping a detection, the result)
LATENT_ACTIONS = frozenset({Action.CYCLE_ON, Action.CYCLE_OFF, Action.VISION_RESULT})
#: the default range (ms), scaled down to DEFAULT_SHARE of time_out when time_out is short
DEFAULT_RANGE_MS = (100.0, 400.0)
#: the default range's top stays within this share of the smaller of time_out and vision_time_out
DEFAULT_SHARE = 0.4


def default_range_ms(profile: Profile) -> tuple[float, float]:
    """The default latency range for this profile: 100–400 ms, inside time_out with room to spare."""
    bound = min(profile.time_out_ms, profile.vision_time_out_ms) * DEFAULT_SHARE
    lo, hi = DEFAULT_RANGE_MS
    return (min(lo, bound / 4), min(hi, bound))


def parse_latency(text: str) -> tuple[float, float]:
    """``MIN-MAX`` or ``N`` in ms (``0``: answer at once) -> (min, max); ValueError with the reason."""
    parts = text.strip().split("-")
    try:
        values = [float(p) for p in parts]
    except ValueError:
        raise ValueError(f"bad --answer-latency {text!r}; expected MIN-MAX in ms (e.g. 100-400) or 0") from None
    if len(values) not in (1, 2):
        raise ValueError(f"bad --answer-latency {text!r}; expected MIN-MAX in ms (e.g. 100-400) or 0")
    lo, hi = values[0], values[-1]
    if not 0 <= lo <= hi <= 600_000:
        raise ValueError(f"bad --answer-latency {text!r}: MIN-MAX must satisfy 0 <= MIN <= MAX (ms)")
    return lo, hi


def check_range(range_ms: tuple[float, float], profile: Profile) -> None:
    """A latency a box may have: below time_out (and vision_time_out, for the result request)."""
    lo, hi = range_ms
    if not 0 <= lo <= hi:
        raise ValueError(f"--answer-latency {lo:g}-{hi:g}: MIN-MAX must satisfy 0 <= MIN <= MAX (ms)")
    bound = min(profile.time_out_ms, profile.vision_time_out_ms)
    if hi >= bound:
        raise ValueError(f"--answer-latency {lo:g}-{hi:g}: the top must stay below time_out/vision_time_out "
                         f"({bound} ms), or the suite itself breaks T1")


class AnswerLatency:
    """The seeded draws of one run (one generator: the draws follow the order the requests arrive in)."""

    def __init__(self, range_ms: tuple[float, float], seed: int) -> None:
        self.range_ms = range_ms
        self.seed = seed
        self._rng = random.Random(seed)

    @property
    def active(self) -> bool:
        return self.range_ms[1] > 0

    def delay_s(self, action: int | None) -> float:
        """The latency of the answer to ``action`` (0 for the requests a box answers at once)."""
        if action not in LATENT_ACTIONS or not self.active:
            return 0.0
        lo, hi = self.range_ms
        return self._rng.uniform(lo, hi) / 1000.0

    def describe(self) -> str:
        lo, hi = self.range_ms
        if not self.active:
            return "answers at once (--answer-latency 0)"
        return (f"CycleOn, CycleOff and the result request answered after {lo:g}–{hi:g} ms, drawn with --seed "
                f"{self.seed}; every other answer at once")


__all__ = ["DEFAULT_RANGE_MS", "LATENT_ACTIONS", "AnswerLatency", "check_range", "default_range_ms",
           "parse_latency"]

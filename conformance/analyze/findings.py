"""What the judgement collects, bounded whatever the capture's size.

* :class:`Findings` holds one :class:`Tally` per (clause, side): how many items were
  judged, how many findings of each verdict, and the first few findings of each
  verdict (with their frame numbers and bytes). The rest are counted, not kept.
* :class:`Series` summarises a long sequence of values in order (answer latencies):
  count, mean, maximum, an evenly spaced sample of at most ``cap`` values (for
  quartile figures and histograms) and the minimum and maximum of each of at most
  ``cap // 4`` consecutive buckets (for plots: every spike stays visible).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from typing import Any

from ..model.percentiles import percentile
from ..model.verdicts import VERDICT_ORDER, Verdict

__all__ = ["BOX", "ROBOT", "SIDES", "Observation", "Findings", "Series", "Tally", "frames_text"]

BOX, ROBOT = "box", "robot"
SIDES = (BOX, ROBOT)
#: findings kept per verdict and case
KEEP = 12


def frames_text(frames: Iterable[int]) -> str:
    """``frame 12``, ``frames 12, 15`` or ``frames 12-14`` (Wireshark's frame.number)."""
    nums = sorted(set(n for n in frames if n))
    if not nums:
        return "no frame"
    if len(nums) == 1:
        return f"frame {nums[0]}"
    if nums[-1] - nums[0] == len(nums) - 1 and len(nums) > 2:
        return f"frames {nums[0]}-{nums[-1]}"
    return "frames " + ", ".join(map(str, nums[:8])) + (" …" if len(nums) > 8 else "")


@dataclass
class Observation:
    verdict: Verdict
    text: str  # one line, naming the connection; the frame numbers are added by :meth:`line`
    frames: tuple[int, ...] = ()
    robot_hex: str = ""  # the robot's bytes that matter (a request), as hex
    box_hex: str = ""  # the box's bytes that matter (an answer)

    def line(self) -> str:
        return f"{frames_text(self.frames)}: {self.text}" if self.frames else self.text


@dataclass
class Tally:
    checked: int = 0
    counts: dict[Verdict, int] = field(default_factory=dict)
    kept: dict[Verdict, list[Observation]] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)
    details: dict[str, Any] = field(default_factory=dict)
    latencies_ms: list[float] = field(default_factory=list)

    def worst(self) -> Verdict | None:
        for verdict in VERDICT_ORDER:
            if self.counts.get(verdict):
                return verdict
        return None

    def note(self, text: str, limit: int = 40) -> None:
        if len(self.notes) < limit:
            self.notes.append(text)
        elif len(self.notes) == limit:
            self.notes.append("… (more notes not kept)")


class Findings:
    """Every (clause, side)'s tally, created on first use."""

    def __init__(self) -> None:
        self.tallies: dict[tuple[str, str], Tally] = {}

    def tally(self, clause: str, side: str) -> Tally:
        t = self.tallies.get((clause, side))
        if t is None:
            t = self.tallies[(clause, side)] = Tally()
        return t

    def check(self, clause: str, side: str, n: int = 1) -> None:
        """``n`` more items judged for this clause (found conforming unless a finding says otherwise)."""
        self.tally(clause, side).checked += n

    def add(self, clause: str, side: str, verdict: Verdict, text: str, frames: Iterable[int] = (),
            robot: bytes = b"", box: bytes = b"") -> None:
        t = self.tally(clause, side)
        t.counts[verdict] = t.counts.get(verdict, 0) + 1
        kept = t.kept.setdefault(verdict, [])
        if len(kept) < KEEP:
            kept.append(Observation(verdict, text, tuple(frames), robot[:2048].hex(" "), box[:2048].hex(" ")))

    def count(self, clause: str, side: str, verdict: Verdict) -> int:
        t = self.tallies.get((clause, side))
        return t.counts.get(verdict, 0) if t else 0


class Series:
    """A long sequence of values in order, in bounded memory."""

    __slots__ = ("n", "total", "max", "max_at", "_step", "_sample", "_cap", "_width", "_peaks", "_lo", "_hi", "_fill")

    def __init__(self, cap: int = 4096) -> None:
        self.n = 0
        self.total = 0.0
        self.max = -math.inf
        self.max_at = 0  # 1-based position of the maximum
        self._cap = cap
        self._step = 1
        self._sample: list[float] = []
        self._width = 1  # values per peak bucket
        self._peaks: list[tuple[float, float]] = []
        self._lo, self._hi, self._fill = math.inf, -math.inf, 0

    def add(self, v: float) -> None:
        n = self.n = self.n + 1
        self.total += v
        if v > self.max:
            self.max, self.max_at = v, n
        if n % self._step == 0:
            self._sample.append(v)
            if len(self._sample) >= self._cap:
                del self._sample[::2]
                self._step *= 2
        if v < self._lo:
            self._lo = v
        if v > self._hi:
            self._hi = v
        self._fill += 1
        if self._fill == self._width:
            self._bucket()

    def extend(self, values: Sequence[float], peaks: bool = True) -> None:
        """Add many values at once (a list or an ``array``); ``peaks=False`` leaves the plot's
        buckets out (for a series that is only sampled, such as a histogram's)."""
        if not len(values):
            return
        n = self.n
        top = max(values)
        if top > self.max:
            self.max, self.max_at = top, n + 1 + list(values).index(top)
        self.total += sum(values)
        self.n = n + len(values)
        self._sample += values[(-(n + 1)) % self._step :: self._step]
        while len(self._sample) >= self._cap:
            del self._sample[::2]
            self._step *= 2
        if not peaks:
            return
        i, size = 0, len(values)
        while i < size:
            chunk = values[i : i + self._width - self._fill]
            lo, hi = min(chunk), max(chunk)
            if lo < self._lo:
                self._lo = lo
            if hi > self._hi:
                self._hi = hi
            self._fill += len(chunk)
            i += len(chunk)
            if self._fill == self._width:
                self._bucket()

    def _bucket(self) -> None:
        self._peaks.append((self._lo, self._hi))
        self._lo, self._hi, self._fill = math.inf, -math.inf, 0
        if len(self._peaks) >= self._cap // 4:
            p = self._peaks
            self._peaks = [(min(p[i][0], p[i + 1][0]), max(p[i][1], p[i + 1][1])) for i in range(0, len(p) - 1, 2)]
            if len(p) % 2:
                self._peaks.append(p[-1])
            self._width *= 2

    @property
    def sample(self) -> list[float]:
        """Every ``step``-th value (at most ``cap`` of them), in order."""
        return list(self._sample)

    @property
    def mean(self) -> float:
        return self.total / self.n if self.n else math.nan

    def percentile(self, q: float) -> float:
        return percentile(self._sample, q) if self._sample else math.nan

    def plot_values(self) -> tuple[list[float], int]:
        """(values to plot, how many values each pair stands for): every value when few,
        else the minimum and maximum of each bucket, in order."""
        if self._width == 1:
            vals = [lo for lo, _ in self._peaks]
            if self._fill:
                vals.append(self._lo)
            return vals, 1
        out: list[float] = []
        for lo, hi in self._peaks:
            out += (lo, hi)
        if self._fill:
            out += (self._lo, self._hi)
        return out, self._width

    def describe(self, unit: str = "ms") -> str:
        if not self.n:
            return "none"
        return (f"n={self.n:,}, p50 {self.percentile(50):.2f} {unit}, p99 {self.percentile(99):.2f} {unit}, "
                f"max {self.max:.2f} {unit}")

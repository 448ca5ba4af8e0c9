"""A threshold pinned by bisection: the smallest count the box refuses, in as few requests as it takes."""

from __future__ import annotations

from collections.abc import Callable


def smallest_refused(accepted: Callable[[int], bool | None], lo: int, hi: int) -> int | None:
    """The smallest n in (lo, hi] with ``accepted(n)`` False, given ``accepted(lo)`` True and ``accepted(hi)``
    False and acceptance that changes once (every count below the threshold accepted, every one from it
    refused). None when a probe could not tell (``accepted`` returned None: out of time, box gone)."""
    while hi - lo > 1:
        mid = (lo + hi) // 2
        ok = accepted(mid)
        if ok is None:
            return None
        if ok:
            lo = mid
        else:
            hi = mid
    return hi

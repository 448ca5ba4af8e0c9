"""``--duration`` and ``--window``: ``30s``, ``90m``, ``2h``, ``1h30m`` (a bare number is seconds).

One parser for every time span the soak takes; bad text is a ValueError whose message is the
one line the command prints before it exits 2.
"""

from __future__ import annotations

import re

#: seconds per unit (``m`` and ``min`` are minutes; ``ms`` is not accepted: a soak is not that short)
UNITS: dict[str, float] = {"s": 1.0, "sec": 1.0, "m": 60.0, "min": 60.0, "h": 3600.0, "d": 86400.0}
_PART = re.compile(r"(\d+(?:\.\d+)?)\s*(d|h|min|m|sec|s)", re.IGNORECASE)
#: the longest span the soak accepts (a week: longer is a typo, or a job for a monitor)
LONGEST_S = 7 * 86400.0


def parse_span(text: str, option: str = "--duration", shortest_s: float = 1.0) -> float:
    """Seconds in ``text`` (``30s``, ``2h``, ``8h``, ``1h30m``, ``45``); ValueError with one line otherwise."""
    raw = text.strip().lower()
    if not raw:
        raise ValueError(f"{option}: empty; expected a span such as 30s, 90m, 2h or 8h")
    if re.fullmatch(r"\d+(?:\.\d+)?", raw):
        seconds = float(raw)
    else:
        pos, seconds = 0, 0.0
        for match in _PART.finditer(raw):
            if match.start() != pos:
                break
            seconds += float(match.group(1)) * UNITS[match.group(2).lower()]
            pos = match.end()
        if pos != len(raw) or pos == 0:
            raise ValueError(f"{option}: {text!r} is not a span; expected a number with a unit, "
                             "such as 30s, 90m, 2h or 8h")
    if not shortest_s <= seconds <= LONGEST_S:
        raise ValueError(f"{option}: {text!r} is out of range; expected {format_span(shortest_s)} to 7 days")
    return seconds


def format_span(seconds: float) -> str:
    """``30s``, ``1m30s``, ``2h``, ``8h05m``: the span as the options write it."""
    if seconds < 60:
        return f"{seconds:g}s"
    total = int(round(seconds))
    hours, rest = divmod(total, 3600)
    minutes, secs = divmod(rest, 60)
    if hours:
        return f"{hours}h" + (f"{minutes:02d}m" if minutes or secs else "") + (f"{secs:02d}s" if secs else "")
    return f"{minutes}m" + (f"{secs:02d}s" if secs else "")


__all__ = ["LONGEST_S", "format_span", "parse_span"]

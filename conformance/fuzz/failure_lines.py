"""How a campaign's failures are printed at its end: deaths (R2) first, each with the box's last words.

A user (or CI) who reads only the first FAIL line learns the worst: that the box died.
A failure that carries the box's last words (:mod:`.last_words`) gets a ``box:`` line
with its headline, then the lines that matter of what the box wrote (a sanitizer report's head, a
traceback, else the last lines).
"""

from __future__ import annotations

from collections.abc import Sequence

from .death_first import deaths_first
from .failure_files import Failure
from .last_words import excerpt

#: Lines of the box's output shown under a failure (the summary and the vector file's note keep more).
TAIL_LINES = 12


def failure_lines(failure: Failure) -> list[str]:
    """The lines printed for one failure."""
    out = [f"  FAIL {failure.number} [{', '.join(failure.clauses)}] {failure.message}",
           f"       vector: {failure.vector}" + (f"  pcap: {failure.pcap}" if failure.pcap else "")]
    words = failure.last_words
    if words is not None:
        out.append(f"       box: {words.summary()}")
        out += [f"       | {line}" for line in excerpt(words, TAIL_LINES)]
    return out


def report_lines(failures: Sequence[Failure]) -> list[str]:
    """Every failure's lines, deaths first."""
    return [line for f in deaths_first(failures) for line in failure_lines(f)]


__all__ = ["TAIL_LINES", "failure_lines", "report_lines"]

"""The box's last words: what a dying box wrote, and the line that says why it died.

Pure functions over the bytes a box wrote to stdout/stderr (kept by :mod:`.box_process`)
and its exit status. :func:`headline` picks the most telling line, strongest first:

1. an AddressSanitizer / UndefinedBehaviorSanitizer / LeakSanitizer report (its
   ``SUMMARY:`` line when there is one, else its ``ERROR:`` or ``runtime error:`` line);
2. a Python traceback (its last line: the exception and its message);
3. ``Segmentation fault``, ``core dumped``, ``Aborted`` lines (a shell or a
   supervisor saying so);
4. the signal that ended the process (from the exit status).

:class:`LastWords` is what a finding carries: the incarnation, its exit status and
signal, the headline and the tail of its output.
"""

from __future__ import annotations

import re
import signal
from dataclasses import asdict, dataclass
from typing import Any

#: At most this much of an incarnation's output is kept (its last bytes).
RING_BYTES = 64 * 1024
#: At most this much of the tail goes into a printed report or a vector file's note.
TAIL_SHOWN = 4096

_SAN_SUMMARY = re.compile(r"SUMMARY: (AddressSanitizer|UndefinedBehaviorSanitizer|LeakSanitizer|ThreadSanitizer|"
                          r"MemorySanitizer): .*")
_SAN_ERROR = re.compile(r"==\d+==\s*ERROR: (AddressSanitizer|LeakSanitizer|ThreadSanitizer|MemorySanitizer): .*")
_UBSAN = re.compile(r"\S+:\d+:\d+: runtime error: .*")
_ACCESS = re.compile(r"(READ|WRITE) of size \d+")
_FRAME = re.compile(r"#\d+ 0x[0-9a-f]+ in (\S+ \S+)")
_RUNTIME = ("__interceptor_", "__asan", "__sanitizer", "__ubsan", "__lsan", "__interceptor")
_TRACEBACK = "Traceback (most recent call last):"
_CRASH_LINE = re.compile(r".*(Segmentation fault|core dumped|Aborted|Bus error|Illegal instruction|"
                         r"Floating point exception).*")


@dataclass
class LastWords:
    """What one incarnation of the box left behind."""

    incarnation: int  # 1 for the first process the campaign started, 2 after the first restart, ...
    pid: int | None
    exit_status: int | None  # None: still running (it hung, or stopped answering without exiting)
    signal: str | None  # the signal that ended it (SIGSEGV ...), also through a shell's 128+N
    headline: str  # the line that says why it died ("" when nothing telling was written)
    kind: str  # "asan", "ubsan", "sanitizer", "traceback", "crash", "signal", "exit", "running" or ""
    tail: str  # the last bytes it wrote (at most RING_BYTES), decoded with replacement
    truncated: bool = False  # more was written than the ring keeps

    def summary(self) -> str:
        """One line: the incarnation, how it ended and the headline."""
        if self.exit_status is None:
            end = "still running"
        else:
            end = f"exit status {self.exit_status}" + (f", {self.signal}" if self.signal else "")
        head = f": {self.headline}" if self.headline else ""
        return f"the box (incarnation {self.incarnation}, pid {self.pid}) {end}{head}"

    def shown_tail(self, limit: int = TAIL_SHOWN) -> str:
        """The tail, cut to its last ``limit`` characters at a line boundary when it is longer."""
        if len(self.tail) <= limit:
            return self.tail
        cut = self.tail[-limit:]
        return "…" + cut[cut.find("\n") + 1 :] if "\n" in cut else "…" + cut

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


def signal_of(status: int | None) -> str | None:
    """The signal name from a ``Popen.returncode`` (negative) or a shell's ``128 + N`` exit status."""
    if status is None or status == 0:
        return None
    number = -status if status < 0 else status - 128 if 128 < status < 160 else 0
    if not number:
        return None
    try:
        return signal.Signals(number).name
    except ValueError:
        return f"signal {number}"


def headline(text: str, status: int | None = None) -> tuple[str, str]:
    """(kind, the line that says why the box died) from its output and exit status; ("", "") when nothing does."""
    lines = text.splitlines()
    start = _sanitizer_start(lines)
    if start is not None:
        return _sanitizer_headline(lines, start)
    tb = _traceback_line(lines)
    if tb:
        return "traceback", tb
    for line in reversed(lines):
        if _CRASH_LINE.fullmatch(line.strip()):
            return "crash", line.strip()
    name = signal_of(status)
    if name:
        return "signal", f"killed by {name}"
    if status:
        return "exit", f"exited with status {status}"
    return ("running", "") if status is None else ("", "")


def _sanitizer_start(lines: list[str]) -> int | None:
    """Where the last sanitizer report starts (its ``ERROR:`` or ``runtime error:`` line, else a ``SUMMARY:``)."""
    for pattern in (_SAN_ERROR, _UBSAN, _SAN_SUMMARY):
        found = [i for i, line in enumerate(lines) if pattern.search(line)]
        if found:
            return found[-1]
    return None


def _sanitizer_headline(lines: list[str], start: int) -> tuple[str, str]:
    """The report's bug type, access and the first stack frame in the box's own code."""
    line = lines[start]
    m = _SAN_ERROR.search(line) or _UBSAN.search(line) or _SAN_SUMMARY.search(line)
    assert m is not None
    found = m.group(0).strip()
    kind = "ubsan" if _UBSAN.search(line) else _sanitizer_kind(found)
    if kind == "ubsan" or found.startswith("SUMMARY:"):
        return kind, found
    bug = re.sub(r" on (unknown )?address.*", "", found.split("ERROR: ", 1)[1])
    access = next((am.group(0) for a in lines[start + 1 : start + 4] if (am := _ACCESS.match(a.strip()))), "")
    where = next((f"in {fm.group(1)}" for f in lines[start + 1 : start + 40] if (fm := _FRAME.search(f))
                  and not fm.group(1).startswith(_RUNTIME)), "")
    return kind, " ".join(x for x in (bug, f"({access})" if access else "", where) if x)


def excerpt(words: LastWords, limit: int = 12) -> list[str]:
    """The lines worth printing: a sanitizer report's head, a traceback, else the last lines written."""
    lines = [line for line in words.tail.splitlines() if line.strip()]
    if words.kind in ("asan", "ubsan", "sanitizer"):
        start = _sanitizer_start(lines)
        if start is not None:
            return lines[start : start + limit]
    if words.kind == "traceback":
        starts = [i for i, line in enumerate(lines) if line.strip() == _TRACEBACK]
        if starts:
            block = lines[starts[-1] :]
            end = next((i for i, line in enumerate(block) if i and not line[0].isspace()), len(block) - 1)
            block = block[: end + 1]
            return block if len(block) <= limit else [block[0], "  ...", *block[-(limit - 2) :]]
    return lines[-limit:]


def _sanitizer_kind(line: str) -> str:
    if "AddressSanitizer" in line:
        return "asan"
    return "ubsan" if "UndefinedBehaviorSanitizer" in line else "sanitizer"


def _traceback_line(lines: list[str]) -> str:
    """The exception line of the last Python traceback: the first unindented line after the header."""
    starts = [i for i, line in enumerate(lines) if line.strip() == _TRACEBACK]
    if not starts:
        return ""
    for line in lines[starts[-1] + 1 :]:
        if line and not line[0].isspace():
            return f"Python traceback: {line.strip()}"
    return "Python traceback (its exception line was not written)"


def last_words(incarnation: int, pid: int | None, status: int | None, output: bytes, truncated: bool = False) -> LastWords:
    """The :class:`LastWords` of one incarnation from its kept output and exit status."""
    text = output.decode("utf-8", "replace")
    kind, line = headline(text, status)
    return LastWords(incarnation, pid, status, signal_of(status), line, kind, text, truncated)




def telling(words: list[LastWords | None]) -> LastWords | None:
    """The first that says why the box died (a headline), else the first there is."""
    there = [w for w in words if w is not None]
    return next((w for w in there if w.headline and w.kind != "running"), there[0] if there else None)


__all__ = ["RING_BYTES", "TAIL_SHOWN", "LastWords", "excerpt", "headline", "last_words", "signal_of", "telling"]

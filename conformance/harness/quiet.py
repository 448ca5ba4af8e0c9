"""Bounded time for a box that goes quiet after bad bytes: the hang pattern.

A case that sends malformed input waits for the probe behind it (its answer bounds the
wait). A box that hangs on a connection after some bad bytes (R6: hanging silently is
NON-STRICT), or drops the probe that shares a segment with bytes it answered (R4), makes
every such case wait the full time_out, 5 s each, some fifty times. A *pattern* is a
family of bad bytes (not a request; a request's header with bad content; an incomplete
frame) and whether the box answered them before going quiet (:func:`pattern_key`).
After :data:`HANG_CASES` cases found the probe unanswered for the whole time_out in one
pattern, with no legal framing explaining the silence (a box that trusts a header and
waits for its body is not hanging), later cases that send that family first wait
:data:`CUT_S` for the probe. If it is answered they are judged as usual; if not, and
they are in the pattern, they end INCONCLUSIVE under it: what the box would have done
later is unknown, so no verdict is guessed. What came before the bound and already
breaks a requirement (a 0000 to malformed input, a malformed answer) is never cut short:
the case then waits out time_out and is judged. Never a FAIL turned PASS.

A pattern is withdrawn as soon as the box answers a probe in it (the silences then had
another cause), and never applies to a case that judges R6 at MUST or SHOULD level: the
cases that report the hang always wait the full time_out. The same bound applies to a
case's second connection on a box that serves one connection at a time
(:meth:`~conformance.suite.case_context.CaseContext.connect`).
"""

from __future__ import annotations

import threading
from dataclasses import dataclass, field

from ..protocol import Frame, Profile, ProtocolError, StreamDecoder, TransferType, Transport
from ..protocol.answers import rule_for_error, rule_for_frame
from ..protocol.framings import Explanation
from ..protocol.splitter import frame_span

#: After this many cases found the probe unanswered behind one kind of bad bytes, later cases are cut short.
HANG_CASES = 2
#: ... to this first wait for the probe's answer (seconds; at most time_out): far above a box's usual answer
#: latency on loopback, far below time_out (each cut case costs it, some fifty of them)
CUT_S = 0.25
#: ... or less on a box whose probe answers came quickly: this many times the slowest of its last
#: :data:`PACE_WINDOW` probe answers, never under :data:`CUT_MIN_S` (a box known to hang is cut about a hundred
#: times in a run, and on a prompt box 250 ms each is a quarter of its whole run)
PACE_FACTOR = 10
PACE_WINDOW = 32
CUT_MIN_S = 0.1
#: The clause a case judges when it reports the hang itself (it always waits the full time_out).
HANG_CLAUSE = "R6"
#: The kinds of bad bytes (:func:`bad_kind`) in words.
KIND_WORDS = {"not-request": "bytes that are not a request", "reject": "a malformed request",
              "reject-should": "a request with a NaN or infinite value",
              "any": "a request whose handling PROTOCOL.md leaves open", "incomplete": "an incomplete frame"}
#: Findings of an explanation that say the box left the probe unanswered with no legal reason.
_HANG_KEYS = ("end/hang", "end/silence")
#: ... and the finding that says the probe was answered with an error (the refused pattern, :func:`refused_key`).
REFUSED_KEYS = ("probe/code",)


def bad_kind(data: bytes, profile: Profile, extension: bool = True) -> str:
    """The kind of the first bad event in ``data`` by the reference framing: what a box may do
    with it (``not-request``, ``reject``, ...), or ``incomplete`` when the bytes leave a frame open."""
    decoder = StreamDecoder(profile, TransferType.ROBOT_TO_BOX)
    for event in decoder.feed(data):
        if isinstance(event, ProtocolError):
            return rule_for_error(event, profile, Transport.TCP, extension).rule.value
        if isinstance(event, Frame):
            exp = rule_for_frame(event, profile, Transport.TCP, extension)
            if not exp.valid:
                return exp.rule.value
    return "incomplete" if decoder.buffered else "valid"


def hung(explanation: Explanation) -> bool:
    """The explanation finds the probe left unanswered where no legal framing allows it."""
    return any(f.key in _HANG_KEYS for f in explanation.findings)


def probe_wronged(explanation: Explanation) -> bool:
    """No legal framing lets the probe go without its 0000: it is left unanswered, or answered with an error,
    where every framing of the bytes before it reaches it (R6 (b) may swallow a probe that begins inside a
    rejected header: 64 KiB of FE read 12 bytes at a time)."""
    return any(f.key in _HANG_KEYS + REFUSED_KEYS for f in explanation.findings)


def broken_besides_hang(explanation: Explanation, also: tuple[str, ...] = ()) -> bool:
    """The explanation finds something wrong other than the silence at the end (or the findings ``also``)."""
    return any(f.key not in _HANG_KEYS + also for f in explanation.findings)


def _family(kind: str) -> str:
    return kind if kind in ("not-request", "incomplete") else "request"


def refused_key(kind: str) -> str:
    """The refused pattern: after this kind of bad bytes the probe's action came back with an error and no
    0000 followed within the wait (a box whose every answer after an error repeats that error: a refusal of
    the bytes may carry the probe's action, A5, so the 0000 is awaited up to time_out)."""
    return f"{_family(kind)}/probe-error"


#: The pattern of a box that reads one frame per segment (R4) however it phrases it: after bytes that are whole
#: frames by their headers (answered or not, requests or not), the probe in the same write went unanswered.
AFTER_FRAMES = "whole-frames/probe-lost"


def whole_frames(data: bytes, profile: Profile) -> bool:
    """``data`` is one or more whole frames by their trusted headers (start word, version 1, a plausible
    length), the last ending at the end of ``data``: a box that reads a frame by its header, whatever it
    makes of the frame, is at a frame's start right after them."""
    at = 0
    while 0 < (span := frame_span(data, at, profile.byte_order)) and at + span <= len(data):
        at += span
    return 0 < at == len(data)


def pattern_keys(kind: str, answered: bool, whole: bool) -> tuple[str, ...]:
    """The patterns one case with these bytes notes: its :func:`pattern_key`, and :data:`AFTER_FRAMES` when the
    bytes are :func:`whole_frames`."""
    return (pattern_key(kind, answered), AFTER_FRAMES) if whole else (pattern_key(kind, answered),)


def pattern_key(kind: str, answered: bool) -> str:
    """A hang pattern: the kind of bad bytes (bytes that are not a request, a frame with a request's header
    and bad content, an incomplete frame), and whether the box answered them before going quiet (a box
    that answers only the first frame of a read drops the probe exactly when it answered the bytes)."""
    return f"{_family(kind)}/{'answered' if answered else 'unanswered'}"


@dataclass
class Hangs:
    """Per pattern (:func:`pattern_key`): the cases that found the probe unanswered for time_out."""

    cases: dict[str, list[str]] = field(default_factory=dict)
    #: patterns after which the box has answered the probe at least once
    answered: set[str] = field(default_factory=set)
    #: the latencies of the last probe answers (seconds): the box's own pace bounds the short wait
    paces: list[float] = field(default_factory=list)
    _lock: threading.Lock = field(default_factory=threading.Lock)

    def paced(self, latency_s: float) -> None:
        """A probe was answered after ``latency_s``."""
        with self._lock:
            self.paces = [*self.paces[-(PACE_WINDOW - 1):], latency_s]

    def cut_s(self, time_out_s: float) -> float:
        """The short first wait: :data:`CUT_S`, or :data:`PACE_FACTOR` times the slowest of the last probe
        answers when that is less (never under :data:`CUT_MIN_S`), at most time_out."""
        with self._lock:
            pace = max(self.paces) * PACE_FACTOR if len(self.paces) >= HANG_CASES else CUT_S
        return min(max(CUT_MIN_S, min(CUT_S, pace)), time_out_s)

    def note(self, key: str, case_id: str, *, hung: bool, probe_answered: bool) -> None:
        with self._lock:
            if probe_answered:
                self.answered.add(key)
            elif hung:
                seen = self.cases.setdefault(key, [])
                if case_id not in seen:
                    seen.append(case_id)

    def known(self, key: str) -> list[str] | None:
        """The cases that established the pattern (None: not established, or withdrawn)."""
        with self._lock:
            cases = self.cases.get(key, [])
            return list(cases) if len(cases) >= HANG_CASES and key not in self.answered else None

    def bound(self, kind: str, judges_hang: bool, time_out_s: float, whole: bool = False) -> float | None:
        """The short first wait for a case sending ``kind`` (``whole``: bytes that are whole frames) when some
        pattern of that kind is established; None (wait in full) otherwise, or when the case judges the hang
        itself (R6 at MUST or SHOULD)."""
        if judges_hang:
            return None
        keys = (pattern_key(kind, False), pattern_key(kind, True), refused_key(kind)) + ((AFTER_FRAMES,) if whole else ())
        if not any(self.known(k) for k in keys):
            return None
        return self.cut_s(time_out_s)

    def known_any(self, keys: tuple[str, ...]) -> tuple[str, list[str]] | None:
        """The first established pattern among ``keys`` and its cases (None: none is)."""
        for key in keys:
            if (cases := self.known(key)) is not None:
                return key, cases
        return None

    def withdraw_refused(self, kind: str) -> None:
        """After this kind of bytes a probe's 0000 came behind an error answer with its action: the refused
        patterns of the kind had another cause."""
        with self._lock:
            self.answered.add(refused_key(kind))

"""Segmentation isolated: the same request sent whole and cut at each split point, and behind a complete frame.

For a root cause whose cases put frames to TCP segmentation (R3: a frame split across segments; R4:
several frames in one segment; S6's bursts list R4), one pose request ``P`` and NONE requests ``N`` go on
fresh connections as these segments (50 ms apart), each followed by a NONE in its own segment (the *tail*,
whose answer tells a dropped frame from a slow one without waiting a whole time_out):

* ``whole``: ``P`` in one segment: the reference (answered as PROTOCOL.md asks, else nothing is isolated);
* ``header`` / ``after-header`` / ``blocks`` / ``check``: ``P`` cut inside its 12-byte header (after byte 5),
  between the header and the blocks (after byte 12), inside the blocks (after byte 20), before its check field;
* ``coalesced``: ``N`` and ``P`` in one segment;
* ``tail-header`` / ``tail-blocks``: ``N`` and the start of ``P`` in one segment (``P`` cut after byte 5 or 20),
  the rest of ``P`` in the next.

Which of them fail, and how (dropped, an error code, a close), is the failure-inducing difference
(:func:`judge`, pure): the split point (inside the header; the blocks in a later segment than the header),
several frames in one segment, or the partial frame a segment ends with. Each story is told apart from
the others by a trial that passes: a partial frame at the end of a segment is lost only when the same cut
alone is answered and the two frames in one segment are too.
"""

from __future__ import annotations

import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

from ..harness.client import Answer, Closed, Malformed, Silence
from ..model.verdicts import CaseResult
from ..protocol.constants import CHECK_LEN, HEADER_LEN
from . import segment_titles as T
from .differences import Isolated
from .experiments import SETTLE_MIN_S, Prober, heard
from .hypotheses import Exchange, Experiment, Heard, Reading
from .probes import GAP_S, _connect

#: the clauses of the cases that put frames to segmentation
CLAUSES = ("R3", "R4")
#: where ``P`` is cut: inside the header, between header and blocks, inside the first block
CUT_HEADER, CUT_BLOCKS = 5, 20
SPLITS = ("header", "after-header", "blocks", "check")
TAILS = ("tail-header", "tail-blocks")
ORDER = ("whole", *SPLITS, "coalesced", *TAILS)


@dataclass(frozen=True)
class Fate:
    """What became of ``P`` in one trial: ``ok`` (answered like the whole), ``error`` (with ``code``),
    ``answered-closed`` (answered like the whole, then the box closed the connection before the NONE behind it,
    the bytes left of ``P`` taken for the start of another frame), ``dropped``
    (never answered, while the tail behind it was), ``closed``, ``silent`` (nothing more came within time_out),
    ``late`` (answered ``ms`` after its last byte, past time_out: see :meth:`Segments._confirm`); ``before``:
    whether the NONE ahead of it in the same segment was answered (None: there was none)."""

    kind: str
    code: int | None = None
    before: bool | None = None
    ms: int | None = None

    @property
    def ok(self) -> bool:
        return self.kind == "ok" and self.before is not False


def pieces(trial: str, none: bytes, pose: bytes) -> tuple[list[bytes], int]:
    """The segments of ``trial`` (before the tail), and how many NONE precede ``P``."""
    cut = {"header": CUT_HEADER, "after-header": HEADER_LEN, "blocks": CUT_BLOCKS, "check": len(pose) - CHECK_LEN,
           "tail-header": CUT_HEADER, "tail-blocks": CUT_BLOCKS}.get(trial)
    if trial == "whole":
        return [pose], 0
    if trial == "coalesced":
        return [none + pose], 1
    assert cut is not None
    if trial in TAILS:
        return [none + pose[:cut], pose[cut:]], 1
    return [pose[:cut], pose[cut:]], 0


def fate_of(answers: Sequence[Heard], closed: bool, action: int, nones: int, reference: int = 0) -> Fate:
    """``P``'s fate from what one trial heard (pure): ``nones`` NONE were sent with it (ahead of it, and the tail),
    ``reference`` is the code the whole ``P`` is answered with."""
    zeros = [a for a in answers if a.action == 0 and a.error == 0]
    before = None if nones < 2 else bool(zeros) and _ahead(answers, action)
    mine = [a for a in answers if a.action == action]
    if mine:
        code = mine[0].error
        if code == reference and closed and len(zeros) < nones:  # answered, then what was left closed the connection
            return Fate("answered-closed", code, before)
        return Fate("ok" if code == reference else "error", code, before)
    if len(zeros) >= nones:
        return Fate("dropped", None, before)
    return Fate("closed" if closed else "silent", None, before)


def _ahead(answers: Sequence[Heard], action: int) -> bool:
    """Whether a NONE answered 0000 came before any answer to ``P`` (the frame ahead of it was answered)."""
    for a in answers:
        if a.action == action:
            return False
        if a.action == 0 and a.error == 0:
            return True
    return False


@dataclass(frozen=True)
class Finding:
    """The isolated difference: ``kind`` (split-header, split-blocks, split-check, split-any, split-at: some cuts,
    coalesced, partial-tail), the trials
    that failed, and how ``P`` fared in them."""

    kind: str
    failed: tuple[str, ...]
    fate: Fate


def judge(fates: Mapping[str, Fate]) -> Finding | None:
    """The failure-inducing difference among the trials (pure); None when the whole frame fails or nothing does."""
    whole = fates.get("whole")
    if whole is None or not whole.ok:
        return None
    split_bad = tuple(t for t in SPLITS if t in fates and not fates[t].ok)
    if split_bad:
        first = fates[split_bad[0]]
        if split_bad in (("header",), ("check",)):
            return Finding(f"split-{split_bad[0]}", split_bad, first)
        if "header" in fates and "header" not in split_bad and {"after-header", "blocks"} & set(split_bad):
            return Finding("split-blocks", split_bad, first)
        if len(split_bad) == len([t for t in SPLITS if t in fates]):
            return Finding("split-any", split_bad, first)
        return Finding("split-at", split_bad, first)
    coalesced = fates.get("coalesced")
    if coalesced is not None and not coalesced.ok:
        return Finding("coalesced", ("coalesced",), coalesced)
    tail_bad = tuple(t for t in TAILS if t in fates and not fates[t].ok)
    if tail_bad and coalesced is not None and all(fates.get(t, whole).ok for t in SPLITS):
        return Finding("partial-tail", tail_bad, fates[tail_bad[0]])
    return None


def involved(members: Sequence[CaseResult]) -> bool:
    """Whether a root cause's cases put frames to segmentation (R3/R4)."""
    return any(set(CLAUSES) & set(m.clauses) for m in members)


class Segments:
    """The trials, run once per diagnose phase; their finding shared by every root cause they explain."""

    def __init__(self, p: Prober) -> None:
        self.p = p
        self.ran = False
        self.found: Isolated | None = None
        self.exchanges: list[Exchange] = []

    def isolate(self, exp: Experiment, members: Sequence[CaseResult]) -> Isolated | None:
        if not involved(members):
            return None
        if not self.ran:
            self.ran = True
            self.found = self._run()
        exp.exchanges += self.exchanges
        return self.found

    def _run(self) -> Isolated | None:
        none, pose = self.p.valid_request(0), self.p.valid_request(0x23)
        fates: dict[str, Fate] = {}
        reference = 0
        for trial in ORDER:
            fate = self._fate(trial, none, pose, reference)
            if fate is None:
                return None
            fates[trial] = fate
            if trial == "whole":
                if fates[trial].kind not in ("ok", "error") or fates[trial].code is None:
                    return None
                reference = fates[trial].code or 0
                fates[trial] = Fate("ok", reference)
            if fates[trial].kind == "silent":  # a box stuck on a partial frame: the trials after it would wait too
                break
        found = judge(fates)
        if found is None or not self._again(found, none, pose, reference):
            return None
        if found.fate.kind == "dropped":  # dropped, or only answered later than the tail's answer?
            late = self._confirm(pieces(found.failed[0], none, pose)[0], pose[5])
            if late is not None:
                found = Finding(found.kind, found.failed, late)
        detail: dict[str, object] = {"segmentation": found.kind, "failed": list(found.failed),
                                     "fate": found.fate.kind, "code": found.fate.code, "ms": found.fate.ms,
                                     "trials": {k: [v.kind, v.code] for k, v in fates.items()}}
        clauses = ("R4", "A1") if found.kind == "coalesced" else ("R3", "R4") if found.kind == "partial-tail" else ("R3",)
        repro = (none, pose) if found.kind in ("coalesced", "partial-tail") else (pose,)
        if found.kind == "coalesced":
            detail["one_write"] = True
        return Isolated(("segmentation", found.kind, found.fate.kind, found.fate.code),
                        T.title(found.kind, found.fate.kind, found.fate.code, pose[5], reference, found.fate.ms, found.failed),
                        clauses, pose[5], repro, detail)

    def _fate(self, trial: str, none: bytes, pose: bytes, reference: int) -> Fate | None:
        segs, ahead = pieces(trial, none, pose)
        got = self._trial(segs, none, ahead + 1)
        return None if got is None else fate_of(got.answers, got.closed, pose[5], ahead + 1, reference)

    def _again(self, found: Finding, none: bytes, pose: bytes, reference: int) -> bool:
        """The first failing trial fails again and the whole frame is answered right again (a box that stalled or
        dropped a frame once, whatever its segments, is not named for a split)."""
        again = self._fate(found.failed[0], none, pose, reference)
        whole = self._fate("whole", none, pose, reference)
        return again is not None and not again.ok and whole is not None and whole.ok

    def _confirm(self, segs: list[bytes], action: int) -> Fate | None:
        """A frame dropped in a trial sent again the same way with no tail behind it, read for up to twice time_out:
        answered past time_out is ``late`` (with the delay); None when nothing came (dropped, confirmed) or the
        deadline leaves no room for the wait."""
        wait = min(2 * self.p.dialer.time_out_s, self.p.left() - 1.0 - GAP_S * len(segs))
        if wait <= self.p.dialer.time_out_s:
            return None
        conn = _connect(self.p)
        if conn is None:
            return None
        answers: list[Heard] = []
        late = None
        try:
            if conn.send_pieces(segs, GAP_S, "diagnose: segmentation, no tail"):
                start = time.monotonic()
                while late is None and time.monotonic() - start < wait:
                    outcome = conn.next_outcome(max(0.0, wait - (time.monotonic() - start)))
                    if isinstance(outcome, (Silence, Closed)):
                        break
                    if isinstance(outcome, (Answer, Malformed)):
                        answers.append(heard(outcome))
                        if answers[-1].action == action:
                            ms = int((time.monotonic() - start) * 1000)
                            if ms > self.p.dialer.time_out_s * 1000:
                                late = Fate("late", answers[-1].error, None, ms)
                            break
        finally:
            conn.close("diagnose")
        self.exchanges.append(Exchange(tuple(segs), (Reading(tuple(answers)),)))
        return late

    def _trial(self, segs: list[bytes], none: bytes, nones: int) -> Reading | None:
        """``segs`` then the tail NONE, each its own segment :data:`GAP_S` apart, on a fresh connection; read until
        every NONE sent was answered 0000 (or a close, or silence for time_out)."""
        if self.p.left() < self.p.dialer.time_out_s + GAP_S * (len(segs) + 1) + 1.0:
            return None
        conn = _connect(self.p)
        if conn is None:
            return None
        answers: list[Heard] = []
        closed = False
        try:
            sent = conn.send_pieces([*segs, none], GAP_S, "diagnose: segmentation")
            while not closed:  # what came before a close is read too (an error answer, then the close)
                outcome = conn.next_outcome(max(0.0, min(self.p.dialer.time_out_s, self.p.left())))
                if isinstance(outcome, Silence):
                    break
                if isinstance(outcome, Closed):
                    closed = True
                    break
                if isinstance(outcome, (Answer, Malformed)):
                    answers.append(heard(outcome))
                if sum(a.action == 0 and a.error == 0 for a in answers) >= nones:
                    answers += [heard(o) for o in conn.drain(SETTLE_MIN_S) if isinstance(o, (Answer, Malformed))]
                    break
        finally:
            conn.close("diagnose")
        reading = Reading(tuple(answers), closed or not sent)
        self.exchanges.append(Exchange((*segs, none), (reading,)))
        return reading

"""The titles of what :mod:`.segments` isolated: which split point fails, or which segment, and how.

Like :mod:`.isolation_titles`: one line, what the box does to the frame (never answers it, answers an
error, closes), the difference that makes it do so in the protocol's words (split inside the header,
the blocks in a later segment than the header, several frames in one segment, the partial frame a
segment ends with), the clause, and after a dash the fix.
"""

from __future__ import annotations

from ..i18n import gettext
from .titles import name


def _code(code: int | None) -> str:
    return "????" if code is None else f"{code:04X}"


def does(fate: str, code: int | None, ms: int | None = None) -> str:
    """What the box does to the frame (``fate``: error, closed, dropped: never answered while the NONE behind it
    is, silent: nothing more within time_out), as a sentence's start: "Never answers", "Answers error 1001 to"."""
    if fate == "error":
        return gettext("Answers error {code} to").format(code=_code(code))
    if fate == "closed":
        return gettext("Closes the connection on")
    if fate == "silent":
        return gettext("Gives no answer within time_out to")
    if fate == "late":
        return gettext("Answers only {ms} ms after its last byte (past time_out)").format(ms=ms)
    if fate == "answered-closed":
        return gettext("Answers before its last bytes have come, then takes them for the start of another frame and "
                       "closes the connection on")
    return gettext("Never answers")


def done(fate: str, code: int | None, ms: int | None = None) -> str:
    """What becomes of the frame, after its subject: "is never answered", "is answered with error 1001"."""
    if fate == "error":
        return gettext("is answered with error {code}").format(code=_code(code))
    if fate == "closed":
        return gettext("makes the box close the connection")
    if fate == "silent":
        return gettext("gets no answer within time_out (nor does anything sent after it)")
    if fate == "late":
        return gettext("is answered only {ms} ms after its last byte (past time_out)").format(ms=ms)
    if fate == "answered-closed":
        return gettext("is answered before its last bytes have come, and they then make the box close the connection")
    return gettext("is never answered")


def cut_name(trial: str) -> str:
    """Where a trial cut the frame, in the protocol's words."""
    names = {"header": gettext("cut after byte 5 (inside the header)"),
             "after-header": gettext("cut after byte 12 (between the header and the blocks)"),
             "blocks": gettext("cut after byte 20 (inside the blocks)"),
             "check": gettext("cut before the check field")}
    return names.get(trial, trial)


def title(kind: str, fate: str, code: int | None, action: int, reference: int, ms: int | None = None,
          failed: tuple[str, ...] = ()) -> str:
    """The title of what :func:`.segments.judge` found (``kind``: split-header, split-blocks, split-check,
    split-any, split-at, coalesced, partial-tail; ``fate`` and ``code``: what became of the frame) for a request
    of ``action`` answered ``reference`` whole (``ms``: how late a late answer came; ``failed``: the trials that
    failed)."""
    what, ref = name(action), _code(reference)
    if kind == "split-header":
        return gettext("{does} a {action} split inside its 12-byte header (cut after byte 5, the rest in a later "
                       "segment; cut after the header, or whole, it is answered {ref}): R3 asks for a split frame handled whole — buffer a partial "
                       "header until its 12 bytes are there").format(does=does(fate, code, ms), action=what, ref=ref)
    if kind == "split-blocks":
        return gettext("{does} a {action} split between its header and its blocks: when the blocks come in a later "
                       "segment than the header (cut after byte 12 or inside the blocks; whole, or cut inside the "
                       "header, it is answered {ref}) it parses the blocks from the read that carried the header — R3: "
                       "wait for all 12+N×L+2 bytes of a frame, across reads, before parsing its blocks").format(
            does=does(fate, code, ms), action=what, ref=ref)
    if kind == "split-check":
        return gettext("{does} a {action} split before its check field (its last 2 bytes in a later segment; whole, or "
                       "cut inside the header or the blocks, it is answered {ref}): R3 asks for a split frame handled "
                       "whole — wait for the check field too before handling the frame").format(
            does=does(fate, code, ms), action=what, ref=ref)
    if kind == "split-any":
        return gettext("{does} a {action} split across TCP segments wherever it is cut (inside the header, after it, "
                       "inside the blocks, before the check field; whole it is answered {ref}): R3 asks for a split "
                       "frame handled whole — buffer until the frame is complete").format(
            does=does(fate, code, ms), action=what, ref=ref)
    if kind == "split-at":
        return gettext("{does} a {action} split across TCP segments {where} (whole, or cut elsewhere, it is answered "
                       "{ref}): R3 asks for a split frame handled whole — buffer until the frame is complete").format(
            does=does(fate, code, ms), action=what, ref=ref, where=", ".join(cut_name(t) for t in failed))
    if kind in ("coalesced", "partial-tail") and fate == "ok":  # the frame is answered, the NONE ahead of it is not
        return gettext("Loses the NONE ahead of a {action} in the same TCP segment (the {action} is answered; each is "
                       "answered when sent alone): R4 asks for every frame of a segment answered — read every whole "
                       "frame in the received bytes").format(action=what)
    if kind == "coalesced":
        return gettext("Handles one frame per segment: when several frames arrive coalesced in one TCP segment, the "
                       "{action} behind a NONE {done} (each is answered when sent alone): R4 asks for every frame of a segment "
                       "answered — keep parsing the receive buffer until no complete frame is left, and keep the "
                       "rest").format(action=what, done=done(fate, code, ms))
    return gettext("Discards the partial frame at the end of a segment: a {action} split across two segments, its "
                   "start behind a complete frame in the first, {done} when its rest comes in the next (cut the same "
                   "way alone, or whole behind the frame, it is answered): R3/R4 ask for a frame continued in the next "
                   "segment handled whole — keep the unparsed remainder of the receive buffer").format(
        action=what, done=done(fate, code, ms))

"""A block length (or a block count of 0) accepted that should be refused: the field isolated, the range measured.

When a root cause's cases quote a block request whose block length L is not its block type's (B1: 25, B2: 5)
and the box answered it 0000, :func:`run` sends the same one-block request with L over a grid (one below, one
above, far above, and lengths whose low byte is the right one: 01 19 is 281), each alone with a NONE behind it,
and :func:`length_story` names the rule the box applies instead of ``L == right`` (pure):

* ``at-least`` — every L above the right one accepted, every L below refused: checks ``L >= 25``;
* ``low-byte`` — exactly the lengths whose low byte is right accepted: reads byte 9 only;
* ``at-most`` — the mirror of ``at-least``; ``any`` — every length tried accepted, below and above;
* ``some`` — otherwise, the accepted lengths listed.

A case that quotes a block request with block count 0 answered 0000 has each block action sent with count 0 alone:
the actions that accept it are named (B5: a block count of 1–255).
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence

from ..i18n import gettext
from ..model.verdicts import CaseResult, RootCause
from ..protocol.constants import HEADER_LEN
from . import titles
from .answer_shape import Order, names
from .experiments import BLOCK_ACTIONS, Prober, block_request
from .families import Found, _accepted, _mech
from .hypotheses import Expect, Experiment, Status

#: the catalogue's stories a wrong block length accepted explains (0000 where a code was expected)
EXPLAINS = ("wrong-code", "fuzz", "unanswered-errors", "block-position")


def grid(right: int) -> list[int]:
    """The block lengths tried for a block type whose length is ``right``."""
    return sorted({right - 1, right + 1, right + 2, right + 5, 2 * right, 100, 255, 0x100 + right, 0x200 + right})


def with_length(frame: bytes, length: int, order: Order = "big") -> bytes:
    """``frame`` (one block) with its block length set to ``length`` (in the header's byte ``order``): the block
    cut or padded with zero bytes."""
    right = int.from_bytes(frame[8:10], order)
    block = frame[HEADER_LEN:HEADER_LEN + right]
    block = (block + bytes(max(0, length - right)))[:length]
    return frame[:8] + length.to_bytes(2, order) + frame[10:HEADER_LEN] + block + frame[-2:]


def quoted(causes: Sequence[RootCause], cases: Sequence[CaseResult]) -> Iterator[tuple[bytes, bytes]]:
    """(sent, received) as the root causes' cases quote them (cut at any "…"), readable ones only."""
    ids = {c for cause in causes for c in cause.cases}
    for case in cases:
        if case.id not in ids:
            continue
        try:
            yield bytes.fromhex(case.sent_hex.partition("…")[0]), bytes.fromhex(case.received_hex.partition("…")[0])
        except ValueError:
            continue


def wrong_lengths(causes: Sequence[RootCause], cases: Sequence[CaseResult], order: Order = "big") -> dict[int, int]:
    """action -> a wrong block length a case quotes for it, answered 0000 (from the root causes' cases)."""
    out: dict[int, int] = {}
    for sent, got in quoted(causes, cases):
        if len(sent) < HEADER_LEN or len(got) < HEADER_LEN or sent[:2] != b"\xfe\xfe":
            continue
        action, length = sent[5], int.from_bytes(sent[8:10], order)
        if action in BLOCK_ACTIONS and length != BLOCK_ACTIONS[action] and got[5] == action and got[10:12] == b"\0\0":
            out.setdefault(action, length)
    return out


def length_story(right: int, results: dict[int, bool | None]) -> tuple[str, list[int], list[int]]:
    """(rule, accepted lengths, refused lengths); rule "" when no wrong length was accepted."""
    accepted = sorted(v for v, ok in results.items() if ok)
    refused = sorted(v for v, ok in results.items() if ok is False)
    if not accepted:
        return "", accepted, refused
    if any(v > 0xFF for v in accepted) and all(v & 0xFF == right for v in accepted) and \
            not any(v & 0xFF == right for v in refused):
        return "low-byte", accepted, refused
    if all(v > right for v in accepted) and all(v < right for v in refused) and len(accepted) >= 3:
        return "at-least", accepted, refused
    if all(v < right for v in accepted) and all(v > right for v in refused):
        return "at-most", accepted, refused
    if not refused and any(v < right for v in accepted) and len(accepted) >= 3:
        return "any", accepted, refused
    return "some", accepted, refused


def _what(action: int) -> str:
    return gettext("pose") if BLOCK_ACTIONS[action] == 25 else gettext("tolerance")


def length_title(action: int, rule: str, right: int, accepted: list[int], refused: list[int]) -> str:
    clause = "B1/B5" if right == 25 else "B2/B5"
    shown = ", ".join(str(v) for v in accepted[:4]) + (" …" if len(accepted) > 4 else "")
    below = ", ".join(str(v) for v in refused[:2]) or "-"
    if rule == "low-byte":
        v = next(v for v in accepted if v > 0xFF)
        return gettext("Reads the block length from its low byte only: block length {hi:02X} {lo:02X} ({v}) is taken as "
                       "{right} and answered 0000 ({below} refused): F4 asks for big-endian 16-bit fields — read "
                       "bytes 8-9 as one number").format(hi=v >> 8, lo=v & 0xFF, v=v, right=right, below=below)
    if rule == "at-least":
        return gettext("Accepts {what} blocks of any block length from {right} up (L = {shown} answered 0000; {below} "
                       "refused): checks L >= {right} instead of L == {right} — {clause} ask for block length exactly "
                       "{right}: refuse any other").format(what=_what(action), right=right, shown=shown, below=below,
                                                          clause=clause)
    if rule == "at-most":
        return gettext("Accepts {what} blocks of any block length up to {right} (L = {shown} answered 0000): checks "
                       "L <= {right} instead of L == {right} — {clause} ask for block length exactly {right}").format(
            what=_what(action), right=right, shown=shown, clause=clause)
    if rule == "any":
        return gettext("Does not check the block length of {what} requests: every block length tried ({low} to {high}) "
                       "is answered 0000 — {clause} ask for block length exactly {right}: refuse any other").format(
            what=_what(action), low=accepted[0], high=accepted[-1], clause=clause, right=right)
    return gettext("Accepts {what} blocks of block length {shown} (answered 0000) where {clause} ask for block length "
                   "exactly {right} — refuse any other").format(what=_what(action), shown=shown, right=right,
                                                               clause=clause)


# -- block count 0 ------------------------------------------------------------------------------------------
def zero_counts(causes: Sequence[RootCause], cases: Sequence[CaseResult]) -> set[int]:
    """The block actions a case quotes with block count 0 (no blocks) answered 0000."""
    out: set[int] = set()
    for sent, got in quoted(causes, cases):
        if len(sent) >= HEADER_LEN and len(got) >= HEADER_LEN and sent[:2] == b"\xfe\xfe" and sent[5] in BLOCK_ACTIONS \
                and sent[7] == 0 and got[5] == sent[5] and got[10:12] == b"\0\0":
            out.add(sent[5])
    return out


def without_blocks(frame: bytes) -> bytes:
    """``frame``'s header with block count 0 and no blocks (block type and length kept), then its check field."""
    return frame[:7] + b"\0" + frame[8:HEADER_LEN] + frame[-2:]


def zero_title(actions: Sequence[int]) -> str:
    named = names(actions)
    return gettext("Accepts {actions} with block count 0 (no blocks at all) and answers 0000: B1/B2/B5 ask for a block "
                   "count of 1–255 — refuse a request with block count 0").format(actions=named)


def _zero_count(p: Prober, causes: Sequence[RootCause], cases: Sequence[CaseResult], found: Found) -> None:
    quoted = zero_counts(causes, cases)
    if not quoted:
        found.stories["block-count"] = (Status.UNTESTED, "no case quotes a block count 0 answered 0000")
        return
    accepted = []
    for action in sorted(BLOCK_ACTIONS):
        if _accepted(p, found.experiment, without_blocks(block_request(p, action, 1))):
            accepted.append(action)
    found.experiment.finding = f"block count 0 accepted for {[f'{a:02X}' for a in accepted]}"
    if not accepted:
        found.stories["block-count"] = (Status.RULED_OUT, "block count 0 refused alone on a fresh connection")
        return
    repro = [(without_blocks(block_request(p, accepted[0], 1)), Expect("invalid", accepted[0]))]
    found.mechanisms.append(_mech("block-count", set(accepted), found, ("B5", "A3", "R1"), repro,
                                  title=zero_title(accepted), explains=EXPLAINS))
    found.stories["block-count"] = (Status.CONFIRMED, found.experiment.finding)


def run(p: Prober, causes: Sequence[RootCause], cases: Sequence[CaseResult]) -> Found:
    found = Found(Experiment("block-length", "the quoted request with other block lengths (and each block action with "
                                             "block count 0), each alone: which does the box accept?"))
    order = p.profile.byte_order
    _zero_count(p, causes, cases, found)
    targets = wrong_lengths(causes, cases, order)
    if not targets:
        found.stories["block-length"] = (Status.UNTESTED, "no case quotes a wrong block length answered 0000")
        return found
    action = min(targets)
    right = BLOCK_ACTIONS[action]
    base = block_request(p, action, 1)
    results: dict[int, bool | None] = {}
    for length in grid(right):
        ok = _accepted(p, found.experiment, with_length(base, length, order))
        if ok is None and p.left() < 1.0:
            break
        results[length] = ok
    rule, accepted, refused = length_story(right, results)
    found.experiment.finding = "; ".join(filter(None, [found.experiment.finding, f"{titles.name(action)}: accepted L "
                                                       f"= {accepted}, refused L = {refused}"]))
    if rule:
        same = {a for a in targets if BLOCK_ACTIONS[a] == right}
        for other in sorted(same - {action}):
            if not _accepted(p, found.experiment, with_length(block_request(p, other, 1), accepted[0], order)):
                same.discard(other)
        repro = [(with_length(base, accepted[0], order), Expect("invalid", action))]
        found.mechanisms.append(_mech("block-length", same, found, ("B1" if right == 25 else "B2", "B5", "R1"), repro,
                                      title=length_title(action, rule, right, accepted, refused), rule=rule,
                                      accepted=accepted, refused=refused, explains=EXPLAINS))
        found.stories["block-length"] = (Status.CONFIRMED, found.experiment.finding)
    else:
        found.stories["block-length"] = (Status.RULED_OUT, found.experiment.finding)
    return found

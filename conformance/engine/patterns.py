"""Root causes read across cases, before any case-level grouping (see :mod:`.rootcause`).

* **A field wrong the same way in every answer** (:func:`field_causes`): the action
  never echoed (A2), one error code whatever the action (A3/A4). Read from the answers'
  header fields that the judging routine keeps in each verdict's :class:`~conformance.model.signature.Reply`.
  A malformed field the decoder names (a constant transfer type, F3; a version, F2) is
  already one signature, grouped by :mod:`.rootcause`.
* **Acceptance that changes at a block position** (:func:`block_position_cause`): valid
  requests refused from block position k on, a wrong index accepted at position k (a box
  that counts indexes in 4 bits, say). Read from the bytes a verdict quotes: the request's
  blocks (their indexes against the profile's first index) and whether the box answered 0000.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from dataclasses import dataclass

from ..i18n import gettext
from ..i18n.ordinals import nth_block
from ..model.signature import Reply, Sig
from ..model.verdicts import CaseResult, RootCause, Verdict
from ..protocol import Action, parse_header
from ..protocol.constants import CHECK_LEN, HEADER_LEN, POSE_BLOCK_LEN, START_WORD, TOLERANCE_BLOCK_LEN, TransferType

#: A field-wide root cause needs at least this many verdicts, about at least two actions.
MIN_FIELD = 3
_JUDGED = (Verdict.FAIL, Verdict.NON_STRICT)
Claim = tuple[RootCause, list[CaseResult]]


def evidence_of(case: CaseResult) -> str:
    """What shows a root cause: the first case it explains, what the box did and the bytes."""
    parts = [f"{case.id}: {case.observed or case.message}"[:300]]
    if case.received_hex:
        parts.append(f"received {case.received_hex[:120]}")
    elif case.sent_hex:
        parts.append(f"sent {case.sent_hex[:120]}")
    return "; ".join(parts)


def _name(action: int) -> str:
    try:
        return Action(action).name
    except ValueError:
        return f"0x{action:02X}"


def _replies(cases: Sequence[CaseResult]) -> list[tuple[CaseResult, Reply]]:
    """The judged verdicts about an answer whose asked-for action is known, with that answer's fields."""
    out = []
    for case in cases:
        sig = case.signature
        if case.verdict in _JUDGED and sig is not None and sig.reply is not None and sig.reply.asked is not None:
            out.append((case, sig.reply))
    return out


def field_causes(cases: Sequence[CaseResult]) -> list[Claim]:
    """A2: the answers' action is one constant value that is not the request's (for at least two
    actions); then A3/A4: among the echoed answers, one error code whatever the action."""
    found: list[Claim] = []
    replies = _replies(cases)
    wrong = [(c, r) for c, r in replies if r.action != r.asked]
    actions = {r.action for _, r in wrong}
    if len(wrong) >= MIN_FIELD and len(actions) == 1 and len({r.asked for _, r in wrong}) >= 2:
        action = actions.pop()
        asked = ", ".join(dict.fromkeys(_name(r.asked) for _, r in wrong if r.asked is not None))
        title = gettext("The action is not echoed: the box answers every request with action {action} "
                        "(asked {asked}); A2 asks for the request's action").format(action=f"{action:02X}", asked=asked)
        found.append((RootCause("", ("A2",), title, evidence_of(wrong[0][0]), kind="action-not-echoed"),
                      [c for c, _ in wrong]))
    echoed = [(c, r) for c, r in replies if r.action == r.asked]
    codes = {r.error for _, r in echoed}
    if len(echoed) >= MIN_FIELD and len(codes) == 1 and len({r.asked for _, r in echoed}) >= 2:
        code = codes.pop()
        clauses = ("A3", "A4") if any(r.asked == Action.NONE for _, r in echoed) else ("A3",)
        title = gettext("The box answers error 0x{code} whatever the action, where the cases expect each action's "
                        "own code ({actions})").format(code=f"{code:04X}",
                                                       actions=", ".join(dict.fromkeys(_name(r.action) for _, r in echoed)))
        found.append((RootCause("", clauses, title, evidence_of(echoed[0][0]), kind="constant-error"),
                      [c for c, _ in echoed]))
    return found


# -- block positions (B3) --------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Blocks:
    """The blocks of the request a verdict quotes: how many, and where the one wrong index is."""

    action: int
    count: int
    wrong_at: int | None  # 0-based position of the one wrong index; None: every index right


_IN_ALL = re.compile(r"\((\d+) bytes in all\)")
_BLOCK_LEN = {1: POSE_BLOCK_LEN, 2: TOLERANCE_BLOCK_LEN}


def blocks_of(sent_hex: str, first_index: int) -> Blocks | None:
    """The request's blocks, read from the hex a verdict quotes (None: not one 23/24/25 request
    whose indexes are all right but at most one). Bytes cut short in the quote are read as far as quoted."""
    head, _, tail = sent_hex.partition("…")
    try:
        raw = bytes.fromhex(head)
    except ValueError:
        return None
    total = int(m.group(1)) if (m := _IN_ALL.search(tail)) else len(raw)
    if len(raw) < HEADER_LEN:
        return None
    header = parse_header(raw)  # only its one-byte fields (and the symmetric start word) are read: any byte order
    if header.start_word != START_WORD or header.transfer_type != TransferType.ROBOT_TO_BOX:
        return None
    action, block_type, count = header.action, header.block_type, header.block_count
    size = _BLOCK_LEN.get(block_type)
    if size is None or count == 0 or total != HEADER_LEN + count * size + CHECK_LEN:
        return None
    wrong = [i for i in range(count) if HEADER_LEN + i * size < len(raw) and raw[HEADER_LEN + i * size] !=
             (first_index + i) & 0xFF]
    if len(wrong) > 1:
        return None
    return Blocks(action, count, wrong[0] if wrong else None)


def _accepted(case: CaseResult, blocks: Blocks) -> bool | None:
    """True: answered 0000; False: refused (a non-zero error, or a close); None: neither is known."""
    sig = case.signature
    if sig is None:
        return None
    if sig.kind is Sig.FUZZ and not sig.field and sig.reply is None and case.verdict is Verdict.FAIL:
        # a fuzz finding quotes the request, not the answer: a valid request fails when it is refused
        # (A1/A3), one with a wrong index when it is answered 0000 (R1/B3)
        judged = set(case.judged or case.clauses)
        if blocks.wrong_at is None:
            return False if judged & {"A1", "A3"} else None
        return True if judged & {"R1", "B3"} else None
    if sig.reply is not None and sig.kind is not Sig.ANSWER:
        return sig.reply.error == 0
    return False if sig.kind is Sig.CLOSED else None


def block_position_cause(cases: Sequence[CaseResult], first_index: int) -> Claim | None:
    """B3: valid block requests refused, or a wrong index accepted, only from some block position
    on (every single-block request judged otherwise). Names that position."""
    members: list[tuple[CaseResult, int, Blocks]] = []  # case, the position it shows, its blocks
    for case in cases:
        if case.verdict not in _JUDGED or not case.sent_hex:
            continue
        blocks = blocks_of(case.sent_hex, first_index)
        accepted = None if blocks is None else _accepted(case, blocks)
        if blocks is None or accepted is None:
            continue
        if blocks.wrong_at is None and not accepted:
            members.append((case, blocks.count - 1, blocks))
        elif blocks.wrong_at is not None and accepted:
            members.append((case, blocks.wrong_at, blocks))
    if not members:
        return None
    k = min(pos for _, pos, _ in members)
    if k < 1:  # a single block refused, or a wrong first index accepted: not a matter of position
        return None
    refused = sorted({b.count for _, _, b in members if b.wrong_at is None})
    accepted_at = sorted({b.wrong_at + 1 for _, _, b in members if b.wrong_at is not None})
    what = []
    if refused:
        what.append(gettext("refuses valid requests of {counts} blocks").format(counts=", ".join(map(str, refused))))
    if accepted_at:
        what.append(gettext("answers 0000 to a wrong index at block {blocks}").format(
            blocks=", ".join(map(str, accepted_at))))
    exact = bool(accepted_at) and min(accepted_at) == k + 1
    where = (gettext("from {block} on") if exact else gettext("at some block up to {block}")).format(block=nth_block(k + 1))
    title = gettext("The box judges block indexes wrongly {where}: it {what}; B3 asks for indexes "
                    "{first}, {second}, … rising by one to the last block").format(
        where=where, what=gettext(" and ").join(what), first=first_index, second=first_index + 1)
    cause = RootCause("", ("B3",), title, evidence_of(min(members, key=lambda m: m[1])[0]), kind="block-position")
    return cause, [c for c, _, _ in members]


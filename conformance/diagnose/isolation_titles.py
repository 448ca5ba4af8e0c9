"""Titles built from an isolated difference (:mod:`.isolate`): the field, byte or threshold, what the box does
there, the clause, and after a dash the direction of the fix. Every string is in the message catalogue."""

from __future__ import annotations

from ..i18n import N_, gettext
from ..i18n.ordinals import nth_block
from .differences import POSE_PARTS
from .titles import name

#: a header field as a title names it, the clause that fixes it, and what that clause allows
_FIELDS = {
    "start_word": (N_("the start word"), "F1", "FE FE"),
    "version": (N_("the version field"), "F2/A5", "00 01"),
    "transfer_type": (N_("the transfer type"), "F3/A5", N_("01 on a request")),
    "action": (N_("the action field"), "A5", N_("the actions PROTOCOL.md defines")),
    "block_type": (N_("the block type"), "B5", N_("the block type the action carries")),
    "block_count": (N_("the block count"), "B5", N_("the block count the action carries")),
    "block_length": (N_("the block length"), "B5/F5", N_("25 for pose blocks, 5 for tolerance blocks, 0 without blocks")),
    "error_code": (N_("the request's error field"), "A3", "00 00"),
    "check": (N_("the check field"), "F6", N_("00 00 or the frame's CRC")),
}


def field_name(field: str) -> str:
    return gettext(_FIELDS.get(field, (field,))[0])


def unchecked(field: str, values: list[str], action: int | None) -> str:
    what, clause, allowed = _FIELDS.get(field, (field, "R1", "its legal values"))
    first, rest = values[0], values[1:]
    more = gettext(" (and {values})").format(values=", ".join(rest)) if rest else ""
    if field == "action":
        return gettext("Answers 0000 to action {value}{more}, which PROTOCOL.md does not define: A5 asks that a frame "
                       "that is not a request is never answered 0000 — refuse unknown actions").format(
            value=first, more=more)
    return gettext("Does not check {field}: answers 0000 to {action} with {field} {value}{more}; {clause} allow only "
                   "{allowed} — refuse a frame whose {field} is wrong").format(
        field=gettext(what), action=name(action), value=first, more=more, clause=clause, allowed=gettext(allowed))


def one_byte(field: str, low: bool, value: str, action: int | None) -> str:
    what, clause, allowed = _FIELDS.get(field, (field, "R1", "its legal values"))
    if field == "start_word":  # a byte pattern, not a number: its first and second byte
        checked, ignored = (gettext("second"), gettext("first")) if low else (gettext("first"), gettext("second"))
        return gettext("Checks only the {checked} byte of the start word: answers 0000 to {action} with the start word "
                       "{value} (its {ignored} byte ignored); F1 allows only FE FE — check both bytes").format(
            checked=checked, ignored=ignored, action=name(action), value=value)
    if low:
        return gettext("Reads only the low byte of {field}: answers 0000 to {action} with {field} {value} (its high "
                       "byte ignored); {clause} allow only {allowed} — read and check both bytes").format(
            field=gettext(what), action=name(action), value=value, clause=clause, allowed=gettext(allowed))
    return gettext("Reads only the high byte of {field}: answers 0000 to {action} with {field} {value} (its low byte "
                   "ignored); {clause} allow only {allowed} — read and check both bytes").format(
        field=gettext(what), action=name(action), value=value, clause=clause, allowed=gettext(allowed))


def length_from_type(value: str, action: int | None, right: int) -> str:
    return gettext("Takes the block length from the block type, not the header: answers 0000 to {action} with block "
                   "length {value} (blocks of {right} bytes); B5/F5 ask for L = {right} in the header — check the "
                   "header's block length against the block type").format(action=name(action), value=value, right=right)


def index_unchecked(block: int, value: int, right: int, first: int, action: int | None) -> str:
    return gettext("Does not check block indexes: answers 0000 to {action} with index {value:02X} at {block} "
                   "(expected {right:02X}); B3 asks for indexes rising by one from {first:02X} — refuse a frame "
                   "whose indexes do not").format(action=name(action), value=value, block=nth_block(block),
                                                  right=right, first=first)


def part_name(action: int | None, part: int) -> str:
    if action in (0x23, 0x24) and part < len(POSE_PARTS):
        return POSE_PARTS[part]
    return gettext("tolerance") if action == 0x25 else gettext("value {n}").format(n=part + 1)


def value_accepted(kind: str, action: int | None, block: int, part: int) -> str:
    return gettext("Accepts {kind} in {action} ({part} of {block}): answers 0000 where B4 asks for a parse error "
                   "(1001/1002) — refuse non-finite values").format(
        kind=kind, action=name(action), part=part_name(action, part), block=nth_block(block))


def value_refused(kind: str, action: int | None, block: int, part: int, what: str) -> str:
    return gettext("Refuses a valid {action} whose {part} ({block}) is {kind}: {what}; B1/B2/B4 allow any finite "
                   "float32 — accept it").format(action=name(action), part=part_name(action, part),
                                                  block=nth_block(block), kind=kind, what=what)


def differs(field: str, value: str, action: int | None, what: str) -> str:
    return gettext("Mishandles {action} when {field} is {value}: {what} (the same request with {field} as PROTOCOL.md "
                   "writes it is answered right) — handle that value as the clause asks").format(
        action=name(action), field=field_name(field), value=value, what=what)


def coalesced(answered: int, sent: int) -> str:
    return gettext("Answers only {k} of {n} requests when several frames arrive in one TCP segment (each is answered "
                   "when sent alone): R4 asks for every frame of a segment answered — read every whole frame in the "
                   "received bytes").format(k=answered, n=sent)


def split(what: str) -> str:
    return gettext("Mishandles a request split across TCP segments ({what}; sent in one write it is answered right): "
                   "R3 asks for a split frame handled whole — buffer until the frame is complete").format(what=what)


def after_prior(prior: str, what: str, last: int | None) -> str:
    return gettext("After {prior} on the same connection the box {what} {action} (on a fresh connection it is "
                   "answered right): A1 asks for every request answered on its own — do not let that request "
                   "change how the connection is served").format(prior=prior, what=what, action=name(last))


def closes_after(prior: str) -> str:
    return gettext("Closes the connection after answering {prior}: the requests behind it on that connection are never "
                   "answered (A1/S1 keep the connection open) — keep serving the connection").format(prior=prior)


def float_order(order: str, kind: str, action: int | None, accepted: bool) -> str:
    what = (gettext("answers 0000 to {kind} written big-endian and refuses it written {order}-endian") if accepted
            else gettext("refuses a valid value written big-endian ({kind}) and accepts it written {order}-endian"))
    return gettext("Decodes the float32 block values {order}-endian (wrong byte order): {what} in {action}; B4 asks for "
                   "big-endian floats (--float-byte-order) — decode them big-endian").format(
        order=order, what=what.format(kind=kind, order=order), action=name(action))


def value_bound(action: int | None, part: str, bound: str, above: bool, code: str) -> str:
    side = gettext("above") if above else gettext("below")
    return gettext("Refuses a valid {action} whose {part} is {side} {bound} ({code}); B1/B2/B4 allow any finite float32 "
                   "— accept every finite value").format(action=name(action), part=part, side=side, bound=bound,
                                                          code=code)


def answer_crc(algorithm: str, order: str, check: str) -> str:
    return gettext("Puts a {algorithm} CRC ({order}-endian, {check} in a NONE answer) in the check field of its TCP "
                   "answers: F6 asks for 00 00 over TCP (the CRC is UDP's) — write 00 00 in TCP answers").format(
        algorithm=algorithm, order=order, check=check)


def answer_check(check: str) -> str:
    return gettext("Writes {check} in the check field of its TCP answers (no CRC of the profile set): F6 asks for "
                   "00 00 over TCP — write 00 00").format(check=check)


def split_header() -> str:
    return gettext("Loses a frame split inside its 12-byte header (split after byte 5 it is never answered; split "
                   "after the header, or whole, it is): R3 asks for a split frame handled whole — buffer a partial "
                   "header until its 12 bytes are there")


def split_bytes() -> str:
    return gettext("Loses a frame sent one byte at a time (split once, or whole, it is answered): R3 asks for a "
                   "split frame handled whole — buffer until the frame is complete")


def split_any() -> str:
    return gettext("Loses a frame split across TCP segments (whole it is answered): R3 asks for a split frame "
                   "handled whole — buffer until the frame is complete")


def no_answer(action: int | None) -> str:
    return gettext("Gives no answer to {action} (none within time_out) while a NONE behind it is answered: A1/T1 ask "
                   "for one answer within time_out — answer every {action}").format(action=name(action))


def cycle_connection(action: int | None, what: str) -> str:
    return gettext("While a cycle is on, {what} {action} on the connection that sent CycleOn (the command "
                   "connection), though the same request on another connection is answered 0000: S3/S1 allow "
                   "poses on the command connection — accept them on every connection").format(
        what=what, action=name(action))


def latency_grows(knee: int, first: float, last: float, n: int, per_connection: bool) -> str:
    where = (gettext("a fresh connection starts fast again: a per-connection history?") if per_connection else
             gettext("a fresh connection is slow too"))
    return gettext("Answer latency grows with the number of requests on a connection, from about request {knee}: "
                   "{first:.0f} ms at first, {last:.0f} ms at request {n} ({where}); T2 asks for a latency that does "
                   "not grow — keep the work per request constant").format(
        knee=knee, first=first, last=last, n=n, where=where)


def length_order(action: int | None, swapped: str, refused: bool) -> str:
    what = gettext("refuses every valid {action}") if refused else gettext("leaves every valid {action} unanswered")
    return gettext("Reads the block length little-endian (wrong byte order): {what} and answers 0000 when its block "
                   "length is written {swapped}; F4 asks for big-endian header fields — read the block length "
                   "big-endian").format(what=what.format(action=name(action)), swapped=swapped)


def done_to(error: int | None, closed: bool) -> str:
    """What the box does to a request, as a verb phrase before it ("answers error 1001 to", ...)."""
    if error is not None:
        return gettext("answers error {code:04X} to").format(code=error)
    return gettext("closes the connection on") if closed else gettext("leaves unanswered")


def did(action: int | None, error: int | None, closed: bool) -> str:
    """What the box did with a request, as a clause ("answers 23 with error 1001", ...)."""
    if error is not None:
        return gettext("answers {action:02X} with error {code:04X}").format(action=action or 0, code=error)
    return gettext("closes the connection") if closed else gettext("leaves it unanswered")


def split_slow(slow_ms: int, fast_ms: int) -> str:
    return gettext("Loses a frame whose pieces arrive {slow} ms apart (an inter-byte timeout?; {fast} ms apart, or "
                   "whole, it is answered): R3 asks for a split frame handled whole whatever the pause — wait for the "
                   "rest of the frame up to time_out").format(slow=slow_ms, fast=fast_ms)

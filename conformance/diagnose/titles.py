"""Root-cause titles a firmware engineer reads once: the mechanism, the threshold, the clause, the fix.

Each title is one line: what the box does (with the number where acceptance changes), a guess
at the cause in parentheses when the number suggests one (128: a count read as signed), the
clause with what it allows, and after a dash the direction of the fix. Ordinals come from
:mod:`conformance.i18n.ordinals` (41st; 第41块).
"""

from __future__ import annotations

from typing import Any

from ..i18n import gettext
from ..i18n.ordinals import nth_block
from ..protocol import Action

#: largest legal frame: 255 pose blocks (F5, B1)
MAX_FRAME = 12 + 255 * 25 + 2
_NAMES = {Action.NONE: "NONE", Action.CYCLE_ON: "CycleOn", Action.CYCLE_OFF: "CycleOff", Action.POSE: "pose",
          Action.REGISTER_POSE: "register pose", Action.TOLERANCE: "tolerance", Action.PROG_IDX: "ProgIdx",
          Action.VISION_RESULT: "result request"}
_BITS = {0x0F: 4, 0x1F: 5, 0x3F: 6, 0x7F: 7}


def name(action: int | None) -> str:
    """An action as a title writes it: "pose (23)"."""
    if action is None:
        return gettext("bytes that are not a request")
    try:
        return f"{_NAMES[Action(action)]} ({action:02X})"
    except (ValueError, KeyError):
        return f"0x{action:02X}"


def count_limit(n: int, per_action: int | None = None) -> str:
    if per_action is not None:
        return gettext("Refuses {action} requests of {n} or more blocks (other requests are accepted up to 255): "
                       "B1/B2/B5 allow a block count of 1–255 — accept every count up to 255").format(
            action=name(per_action), n=n)
    if n == 128:
        return gettext("Refuses every request of 128 or more blocks (count read as signed?): B1/B5 allow a block "
                       "count of 1–255 — read the block count as an unsigned byte")
    return gettext("Refuses every request of {n} or more blocks (a limit of {m}?): B1/B5 allow a block count of "
                   "1–255 — accept every count up to 255").format(n=n, m=n - 1)


#: buffer sizes a firmware is likely to have: named when one lies between the largest accepted and smallest refused frame
ROUND_SIZES = (256, 500, 512, 768, 1000, 1024, 1200, 1280, 1400, 1460, 1500, 2000, 2048, 4000, 4096)


def byte_limit(max_bytes: int, examples: str, refused_bytes: int | None = None) -> str:
    """``max_bytes``: the largest frame seen accepted; ``refused_bytes``: the smallest seen refused."""
    top = refused_bytes if refused_bytes is not None else max_bytes + 1
    guess = next((n for n in ROUND_SIZES if max_bytes <= n < top), None)
    if guess is not None:
        return gettext("Refuses every frame longer than {n} bytes (a {n}-byte receive buffer?): {examples}; F5/B5 "
                       "allow frames of up to {max} bytes — size the buffer for 255 pose blocks").format(
            n=guess, examples=examples, max=MAX_FRAME)
    return gettext("Refuses every frame of {top} bytes or more (frames of {n} bytes are accepted): {examples}; F5/B5 "
                   "allow frames of up to {max} bytes — size the buffer for 255 pose blocks").format(
        top=top, n=max_bytes, examples=examples, max=MAX_FRAME)


def index(block: int, value: int, right: int, threshold: int) -> str:
    bits = next((b for mask, b in _BITS.items() if value == right & mask), None)
    guess = gettext(" (a {bits}-bit index counter?)").format(bits=bits) if bits else ""
    return gettext("Judges block indexes wrongly from {block} on: answers 0000 to index {value} there and refuses the "
                   "right index {right}{guess}: B3 asks for indexes rising by one to the last block — compare the "
                   "index as a full byte").format(block=nth_block(block), value=value, right=right, guess=guess)


def extra_answer(action: int, count: int) -> str:
    times = gettext("twice") if count == 2 else gettext("{n} times").format(n=count)
    return gettext("Answers every {action} {times}: every later answer on the connection is shifted by one; A1 asks "
                   "for exactly one answer per request — send one answer per request").format(action=name(action), times=times)


def echo_one(action: int, wrong: int | None) -> str:
    return gettext("Answers {action} with action {wrong} (copied from another action's answer?): A2 asks for the "
                   "request's action echoed — echo {code:02X}").format(
        action=name(action), wrong="??" if wrong is None else f"{wrong:02X}", code=action)


def echo_all(value: int | None, actions: str) -> str:
    return gettext("Answers every request with action {wrong} ({actions} asked): A2 asks for the request's action "
                   "echoed — copy the request's action into its answer").format(
        wrong="??" if value is None else f"{value:02X}", actions=actions)


def missing(action: int) -> str:
    return gettext("Gives no answer to {action} (none within time_out), and goes on serving the connection: A1/T1 "
                   "ask for one answer within time_out — answer every {action}").format(action=name(action))


def refuses(action: int, code: int | None) -> str:
    return gettext("Refuses every valid {action} with error {code}: A1/A3 ask for 0000 to a valid request — accept "
                   "it").format(action=name(action), code="????" if code is None else f"{code:04X}")


def state_leak(action: int, what: str) -> str:
    return gettext("After it answers a request with an error, the box {what} the next valid {action} on that "
                   "connection (error state kept?): A1/A3 judge every request on its own — clear the error after "
                   "each answer").format(action=name(action), what=what)


def cycle_dependent(action: int, inside: bool, what: str) -> str:
    when = gettext("while a cycle is on") if inside else gettext("while no cycle is on")
    return gettext("{What} {action} {when}: S3 asks for poses accepted whether or not a cycle is on — accept them in "
                   "every cycle state").format(What=what, action=name(action), when=when)


def connection_count(n: int) -> str:
    return gettext("Stops answering properly after {n} requests on one connection (a per-connection counter?): A1 "
                   "asks for every request answered — do not limit requests per connection").format(n=n)


def unconfirmed(title: str) -> str:
    return gettext("unconfirmed: {title}").format(title=title)


def size_undecided(count: int, max_bytes: int, refused_bytes: int, accepted: str) -> str:
    """A block count refused at one block size only, where no legal frame of another size is as long: a frame-size
    limit and a count limit both fit (the title of an unconfirmed root cause; ``accepted``: what other sizes did)."""
    powers = [1 << k for k in range(8, 17) if max_bytes <= 1 << k < refused_bytes]
    buffer = gettext(" (a {size}-byte receive buffer?)").format(size=powers[0]) if powers else ""
    return gettext("Refuses pose requests of {count} or more blocks ({refused} bytes; {below} blocks, {max} bytes, "
                   "answered 0000) while {accepted}: a limit on the frame's size in bytes, between {max} and {refused}"
                   "{buffer}, or on the count of 25-byte blocks; no legal frame of another block size is that long "
                   "to tell them apart — B5 allows 255 blocks").format(
        count=count, refused=refused_bytes, below=count - 1, max=max_bytes, accepted=accepted, buffer=buffer)


def of(kind: str, detail: dict[str, Any]) -> str:
    """The title of a confirmed mechanism from its kind and numbers (see :mod:`.families`)."""
    d = detail
    if kind == "count-limit":
        return count_limit(int(d["threshold"]), d.get("per_action"))
    if kind == "byte-limit":
        return byte_limit(int(d["max_bytes"]), str(d.get("examples", "")), d.get("refused_bytes"))
    if kind == "index":
        return index(int(d["block"]), int(d["value"]), int(d["right"]), int(d["threshold"]))
    if kind == "extra-answer":
        return extra_answer(int(d["action"]), int(d["count"]))
    if kind == "echo-one":
        return echo_one(int(d["action"]), d.get("answered"))
    if kind == "echo-all":
        return echo_all(d.get("answered"), str(d.get("asked", "")))
    if kind == "missing-answer":
        return missing(int(d["action"]))
    if kind == "refuses-valid":
        return refuses(int(d["action"]), d.get("error"))
    if kind == "state-leak":
        return state_leak(int(d["action"]), str(d["what"]))
    if kind == "cycle-dependent":
        return cycle_dependent(int(d["action"]), bool(d["inside"]), str(d["what"]))
    if kind == "connection-count":
        return connection_count(int(d["n"]))
    return str(d.get("title", kind))

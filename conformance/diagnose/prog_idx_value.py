"""The ProgIdx value echoed (E1, E2): which reading of the int32 the box's echo shows.

A box whose answer to ProgIdx carries another value than the one sent may read the int32 from fewer bytes than
four, in the other byte order, or not at all. ProgIdx requests with values chosen so that each reading gives a
different echo (small ones, across a byte and a 16-bit boundary, negative, every byte distinct) are sent on fresh
connections; the one transform that maps every value sent to the value echoed is the mechanism. A 409 (conflict,
not ready) says nothing about the reading and is left out. :func:`reading` is the pure verdict.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Sequence

from ..i18n import gettext
from ..protocol import Action, Transport, ValueBlock, request
from ..protocol.answers import CONFLICT, block_value
from .experiments import Prober
from .families import Found, _mech
from .hypotheses import Expect, Experiment, Status

PROG_IDX = int(Action.PROG_IDX)
#: the values sent: each reading below gives a different echo for at least two of them
VALUES = (7, 255, 256, 65535, 65536, 70000, -1, 0x01020304, 2**31 - 1, -(2**31))


def _s32(v: int) -> int:
    v &= 0xFFFFFFFF
    return v - (1 << 32) if v & 0x80000000 else v


def _s16(v: int) -> int:
    v &= 0xFFFF
    return v - (1 << 16) if v & 0x8000 else v


#: (the reading in words, what it echoes for a value sent); the first that fits every echo is the mechanism
READINGS: tuple[tuple[str, Callable[[int], int]], ...] = (
    ("low two bytes, unsigned", lambda v: v & 0xFFFF),
    ("low two bytes, signed", lambda v: _s16(v)),
    ("low byte", lambda v: v & 0xFF),
    ("little-endian", lambda v: _s32(int.from_bytes((v & 0xFFFFFFFF).to_bytes(4, "big"), "little"))),
    ("unsigned", lambda v: v & 0xFFFFFFFF),
    ("always 0", lambda v: 0),
)


def reading(pairs: Iterable[tuple[int, int]]) -> str:
    """The one reading that maps every value sent to the value echoed ("" when the echo is right, or fits none)."""
    seen = [(v, e) for v, e in pairs if e != CONFLICT]
    if not seen or all(v == e for v, e in seen):
        return ""
    return next((name for name, f in READINGS if all(f(v) == e for v, e in seen)), "")


def title(name: str, pairs: Sequence[tuple[int, int]]) -> str:
    wrong = [(v, e) for v, e in pairs if v != e and e != CONFLICT][:2]
    right = [v for v, e in pairs if v == e][:2]
    shown = ", ".join(gettext("{sent} comes back as {got}").format(sent=v, got=e) for v, e in wrong)
    kept = gettext(" ({right} echoed right)").format(right=", ".join(str(v) for v in right)) if right else ""
    if name.startswith("low"):
        part, _, how = name.partition(", ")
        parts = {"low two bytes": gettext("low two bytes"), "low byte": gettext("low byte")}
        hows = {"unsigned": gettext("unsigned"), "signed": gettext("signed")}
        what = gettext("Echoes only the {part} of the ProgIdx int32").format(part=parts.get(part, part)) + (
            gettext(" (read {how})").format(how=hows.get(how, how)) if how else "")
    elif name == "little-endian":
        what = gettext("Reads the ProgIdx int32 little-endian")
    elif name == "unsigned":
        what = gettext("Echoes the ProgIdx int32 as unsigned")
    else:
        what = gettext("Echoes 0 whatever the ProgIdx")
    return gettext("{what}: {shown}{kept}; E1/E2 ask for the signed big-endian int32 echoed whole — read all four "
                   "bytes, big-endian, signed").format(what=what, shown=shown, kept=kept)


def run(p: Prober, asked: Iterable[int]) -> Found:
    found = Found(Experiment("progidx-value", "ProgIdx requests with values each reading of the int32 echoes "
                                              "differently: which reading maps every value sent to the echo?"))
    if PROG_IDX not in set(asked):
        return found
    pairs: list[tuple[int, int]] = []
    frames: dict[int, bytes] = {}
    for value in VALUES:
        frame = p.codec.encode(request(Action.PROG_IDX, [ValueBlock(p.profile.first_index, value)]), Transport.TCP)
        ex = p.exchange([frame], settle=False)
        if ex is None or not ex.reached:
            break
        found.experiment.exchanges.append(ex)
        answers = ex.reading(0).answers
        echoed = block_value(answers[0].raw, p.profile.byte_order) if answers else None
        if echoed is None:
            break  # no type-03 block: the answer shape family speaks for it
        pairs.append((value, echoed))
        frames[value] = frame
    name = reading(pairs)
    found.experiment.finding = "; ".join(f"{v} -> {e}" for v, e in pairs) + (f": {name}" if name else "")
    if name:
        wrong = next(v for v, e in pairs if v != e and e != CONFLICT)
        found.mechanisms.append(_mech("answer-shape", {PROG_IDX}, found, ("E1", "E2"),
                                      [(frames[wrong], Expect("valid", PROG_IDX))], title=title(name, pairs),
                                      field="value", reading=name))
        found.stories["progidx-value"] = (Status.CONFIRMED, found.experiment.finding)
    else:
        found.stories["progidx-value"] = (Status.RULED_OUT if pairs else Status.UNTESTED, found.experiment.finding)
    return found

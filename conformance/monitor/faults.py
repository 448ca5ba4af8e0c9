"""``--fault`` specs: what the monitor does to the box's answers, and when (sans-I/O).

A spec is ``KIND:ACTION[:ARG][,OPTION=VALUE...]``:

======================  ===========================================================================
``delay:ACTION:MS``     the answer to ACTION reaches the robot MS ms late (and what follows it on
                        that connection waits behind it, as behind a late box)
``drop:ACTION``         the answer to ACTION never reaches the robot
``error:ACTION:CODE``   the robot gets ACTION's answer with error code CODE and no blocks instead
``corrupt:ACTION:FIELD`` one field of the answer is inverted (every bit): ``start``, ``version``,
                        ``type``, ``action``, ``blocktype``, ``count``, ``length``, ``error``,
                        ``body`` (its first byte) or ``check``
``close:ACTION``        instead of the answer to ACTION the robot's connection is closed (FIN),
                        and the monitor's connection to the box with it
``stall:ACTION:MS``     from the answer to ACTION on, every answer on every connection is held
                        MS ms (a box that freezes), then released in order
======================  ===========================================================================

ACTION is a name (``CYCLE_ON``, ``cycleon``, ``cycle-on``), a number (``1``, ``0x23``) or
``any``. Options: ``every=N`` (every Nth matching answer; default 1), ``p=P`` (each with
probability P, from ``seed=S``), ``count=K`` (at most K times), ``after=S`` (not in the
monitor's first S seconds). The first spec that matches an answer applies.
"""

from __future__ import annotations

import random
from dataclasses import dataclass, field

from ..protocol import HEADER_LEN, Action
from ..protocol.constants import HEADER_FIELDS

__all__ = ["FIELDS", "KINDS", "Fault", "FaultPlan", "corrupt", "parse_fault"]

KINDS = ("delay", "drop", "error", "corrupt", "close", "stall")
#: field name -> (offset from the frame's start, or from its end when negative; width)
FIELDS: dict[str, tuple[int, int]] = {
    **{short: HEADER_FIELDS[name] for short, name in (
        ("start", "start_word"), ("version", "version"), ("type", "transfer_type"), ("action", "action"),
        ("blocktype", "block_type"), ("count", "block_count"), ("length", "block_length"), ("error", "error_code"))},
    "body": (HEADER_LEN, 1), "check": (-2, 2),
}
#: what each kind imitates, for the report: the clause a real box would break
CLAUSE = {"delay": "T1", "drop": "A1", "error": "A3", "corrupt": "F1", "close": "S5", "stall": "T1"}


def _action(text: str) -> int | None:
    t = text.strip().lower().replace("_", "").replace("-", "")
    if t == "any":
        return None
    for a in Action:
        if a.name.lower().replace("_", "") == t:
            return int(a)
    try:
        value = int(t, 0)
    except ValueError:
        raise ValueError(f"unknown action {text!r} (a name such as CYCLE_ON, a number, or any)") from None
    if not 0 <= value <= 255:
        raise ValueError(f"action {text!r} is not a byte")
    return value


@dataclass
class Fault:
    spec: str
    kind: str
    action: int | None
    ms: float = 0.0
    code: int = 0
    field_name: str = ""
    every: int = 1
    p: float | None = None
    count: int | None = None
    after_s: float = 0.0
    rng: random.Random = field(default_factory=random.Random)
    seen: int = 0
    injected: int = 0

    @property
    def clause(self) -> str:
        return CLAUSE[self.kind]

    def hit(self, action: int, elapsed_s: float) -> bool:
        """One answer with ``action``, ``elapsed_s`` after the start: inject now?"""
        if (self.action is not None and action != self.action) or elapsed_s < self.after_s:
            return False
        if self.count is not None and self.injected >= self.count:
            return False
        self.seen += 1
        hit = self.rng.random() < self.p if self.p is not None else self.seen % self.every == 0
        if hit:
            self.injected += 1
        return hit


def _options(fault: Fault, options: list[str], seed: int) -> None:
    fault.rng = random.Random(seed)
    for opt in options:
        key, eq, value = opt.partition("=")
        key = key.strip()
        try:
            if not eq:
                raise ValueError
            if key == "every":
                fault.every = int(value)
                if fault.every < 1:
                    raise ValueError
            elif key == "p":
                fault.p = float(value)
                if not 0 < fault.p <= 1:
                    raise ValueError
            elif key == "seed":
                fault.rng = random.Random(int(value))
            elif key == "count":
                fault.count = int(value)
                if fault.count < 1:
                    raise ValueError
            elif key == "after":
                fault.after_s = float(value)
                if fault.after_s < 0:
                    raise ValueError
            else:
                raise KeyError(key)
        except KeyError:
            raise ValueError(f"--fault {fault.spec!r}: unknown option {key!r} (every, p, seed, count, after)") from None
        except ValueError:
            raise ValueError(f"--fault {fault.spec!r}: bad {opt!r} (every=N >= 1, p in (0, 1], seed=N, "
                             "count=K >= 1, after=S >= 0)") from None


def parse_fault(spec: str, seed: int = 0) -> Fault:
    """A :class:`Fault` from its spec; ValueError (one line) when malformed."""
    head, *options = spec.split(",")
    parts = head.split(":")
    kind = parts[0].strip().lower()
    if kind not in KINDS:
        raise ValueError(f"--fault {spec!r}: unknown kind {kind!r} (one of {', '.join(KINDS)})")
    wants_arg = kind in ("delay", "error", "corrupt", "stall")
    if len(parts) != (3 if wants_arg else 2):
        shape = f"{kind}:ACTION" + (":" + {"delay": "MS", "stall": "MS", "error": "CODE", "corrupt": "FIELD"}[kind]
                                    if wants_arg else "")
        raise ValueError(f"--fault {spec!r}: expected {shape}[,option=value...]")
    try:
        fault = Fault(spec, kind, _action(parts[1]))
    except ValueError as exc:
        raise ValueError(f"--fault {spec!r}: {exc}") from None
    if wants_arg:
        arg = parts[2].strip()
        try:
            if kind in ("delay", "stall"):
                fault.ms = float(arg)
                if not 0 < fault.ms <= 3_600_000:
                    raise ValueError
            elif kind == "error":
                fault.code = int(arg, 0)
                if not 0 <= fault.code <= 0xFFFF:
                    raise ValueError
            elif arg.lower() in FIELDS:
                fault.field_name = arg.lower()
            else:
                raise ValueError
        except ValueError:
            want = {"delay": "MS in (0, 3600000]", "stall": "MS in (0, 3600000]", "error": "a code 0..65535",
                    "corrupt": "one of " + ", ".join(FIELDS)}[kind]
            raise ValueError(f"--fault {spec!r}: bad {arg!r}: expected {want}") from None
    _options(fault, options, seed)
    return fault


def corrupt(frame: bytes, field_name: str) -> bytes:
    """``frame`` with every bit of one field inverted (a field the frame is too short for: its last byte)."""
    offset, width = FIELDS[field_name]
    start = offset if offset >= 0 else len(frame) + offset
    if start < 0 or start + width > len(frame) or (field_name == "body" and len(frame) <= HEADER_LEN + 2):
        start, width = len(frame) - 1, 1
    out = bytearray(frame)
    for i in range(start, start + width):
        out[i] ^= 0xFF
    return bytes(out)


class FaultPlan:
    """The specs in order; :meth:`pick` the one that applies to an answer."""

    def __init__(self, specs: list[str], seed: int = 0) -> None:
        self.faults = [parse_fault(s, seed + i) for i, s in enumerate(specs)]

    def __bool__(self) -> bool:
        return bool(self.faults)

    def pick(self, action: int, elapsed_s: float) -> Fault | None:
        for fault in self.faults:
            if fault.hit(action, elapsed_s):
                return fault
        return None

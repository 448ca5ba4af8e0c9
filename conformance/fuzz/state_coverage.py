"""State coverage of the session fuzzer: which (cycle state, connection, last answer) -> request transitions it reached.

Like AFLNet's state model, a session is a walk over states; here a state is what a
conforming box's answer may depend on:

* the cycle state (S2, S3): idle or on, as the machine knows it (unknown states are not counted);
* the connection: ``command`` or ``stream`` (a robot may send any request on either, S4);
* the last answer on that connection: ``open`` (none yet), or the action of the last
  request the box answered there with a code :data:`~conformance.protocol.answers.ALLOWED_CODES` allows.

A *transition* is a state and the next request's action; it is *reached* when the box
answers that request with an allowed code. The space is every transition the protocol
allows: every session action (ProgIdx and the result request only with extension E)
from every state, except a last answer of CycleOn in the idle state and of CycleOff in
the on state (a box that accepts CycleOn is then on: only a refusal leaves it idle).
:meth:`StateCoverage.unreached` gives what is left in a fixed order (seeded), so the
steering of :mod:`.session_machine` walks toward it; ``to_dict()`` goes into ``fuzz-summary.json``.
"""

from __future__ import annotations

import random
from typing import Any, NamedTuple

from ..protocol import Action
from ..protocol.answers import Cycle, allowed_codes

CONNECTIONS = ("command", "stream")
CORE = (Action.NONE, Action.CYCLE_ON, Action.CYCLE_OFF, Action.POSE, Action.REGISTER_POSE, Action.TOLERANCE)
EXTENDED = (Action.PROG_IDX, Action.VISION_RESULT)
OPEN = "open"


class Transition(NamedTuple):
    cycle: str  # Cycle.IDLE / Cycle.ON value
    connection: str
    last: str  # "open" or the action name of the last answered request on the connection
    action: str  # the request's action name

    def describe(self) -> str:
        return f"cycle {self.cycle}, {self.connection} connection, last answer {self.last} -> {self.action}"


def session_actions(extension: bool) -> tuple[Action, ...]:
    return CORE + (EXTENDED if extension else ())


def space(extension: bool) -> tuple[Transition, ...]:
    """Every transition the protocol allows (see the module docstring)."""
    actions = session_actions(extension)
    out = []
    for cycle in (Cycle.IDLE, Cycle.ON):
        for conn in CONNECTIONS:
            for last in (OPEN, *(a.name for a in actions)):
                if (cycle, last) in ((Cycle.IDLE, "CYCLE_ON"), (Cycle.ON, "CYCLE_OFF")):
                    continue
                out += [Transition(cycle.value, conn, last, a.name) for a in actions]
    return tuple(out)


def accepted(action: Action, cycle: Cycle, code: int) -> bool:
    """The box answered ``action`` in ``cycle`` with a code the protocol allows."""
    allowed = allowed_codes(action, cycle)
    return allowed is None or code in allowed


class StateCoverage:
    """Transitions reached by the session machine, out of :func:`space`."""

    def __init__(self, extension: bool, seed: int = 0) -> None:
        self.space = space(extension)
        self._known = frozenset(self.space)
        self.reached: dict[Transition, set[int]] = {}  # -> the answer codes seen
        self.extra: set[Transition] = set()  # reached, but outside the space (e.g. CycleOn refused)
        self._order = list(self.space)
        random.Random(seed).shuffle(self._order)

    def record(self, cycle: Cycle | None, connection: str, last: str | None, action: Action, code: int) -> None:
        if cycle is None or cycle is Cycle.UNKNOWN or last is None or not accepted(action, cycle, code):
            return
        t = Transition(cycle.value, connection, last, action.name)
        if t in self._known:
            self.reached.setdefault(t, set()).add(code)
        else:
            self.extra.add(t)

    def unreached(self) -> list[Transition]:
        return [t for t in self._order if t not in self.reached]

    @property
    def fraction(self) -> float:
        return round(len(self.reached) / len(self.space), 4) if self.space else 1.0

    def to_dict(self) -> dict[str, Any]:
        return {
            "reached": len(self.reached), "of": len(self.space), "fraction": self.fraction,
            "outside_the_space": len(self.extra),
            "unreached": [t.describe() for t in self.unreached()[:12]],
        }


__all__ = ["CONNECTIONS", "OPEN", "StateCoverage", "Transition", "accepted", "session_actions", "space"]

"""Is the box alive? (R2) One liveness check for the catalogue, the fuzzer and replay.

A liveness check is a NONE request on a *fresh* connection: whatever the bytes sent
on another connection did, a conforming box keeps accepting and answering new ones
(R2). What the box did is an :data:`~.client.Outcome`, never an exception: a refused
connection is a reset (:class:`~.client.Closed`), any other unreachable target a
silence as long as time_out. :func:`responsive` says whether an outcome shows a box
that still answers (a frame-like answer, right or wrong: the cases judge the rest).
"""

from __future__ import annotations

import select
from collections.abc import Callable

from ..protocol import Action, Frame, Profile, request
from .client import Answer, Closed, Malformed, Outcome, Silence, TcpConnection
from .target import Refused, Target, Unreachable
from .transcript import Transcript

#: The liveness request (and the first choice of probe): NONE is answered 0000 in every state (A4).
PROBE_NONE: Frame = request(Action.NONE)
LIVENESS_NOTE = "liveness check on a fresh connection (R2)"


def responsive(outcome: Outcome) -> bool:
    """The box answered with something frame-like (a readable header), whether right or not."""
    if isinstance(outcome, Answer):
        return True
    return isinstance(outcome, Malformed) and outcome.error.header is not None


def unreachable_outcome(exc: Unreachable, time_out_s: float) -> Outcome:
    """What a connection attempt that failed looks like to a case: refused is a reset, else silence."""
    return Closed(True, 0.0) if isinstance(exc, Refused) else Silence(time_out_s)


def check_alive(transcript: Transcript, target: Target, profile: Profile, *, time_out_s: float | None = None,
                label: str = "liveness", note: str = LIVENESS_NOTE) -> Outcome:
    """R2: a NONE request on a fresh connection; what the box did (never an exception).

    ``time_out_s`` None: the profile's time_out, and a wait that runs it out counts in
    ``transcript.timeouts`` (the session reads it)."""
    conn = TcpConnection(transcript, target, profile, label, time_out_s)
    try:
        conn.connect()
    except Unreachable as exc:
        return unreachable_outcome(exc, conn.time_out_s)
    outcome = conn.request(PROBE_NONE, note)
    conn.close()
    return outcome


def still_quiet(conn: TcpConnection) -> bool:
    """Nothing has arrived on ``conn`` that was not read yet (one last look before a short wait is taken for a
    silence: a box kept from running for a moment answers now)."""
    if conn.sock is None or not conn.is_open:
        return True
    try:
        return not select.select([conn.sock], [], [], 0)[0]
    except (OSError, ValueError):
        return True


def cut_holds(alive: Outcome, conn: TcpConnection, paced: Callable[[float], None]) -> bool:
    """After a short wait ran out on ``conn`` and a liveness check answered ``alive``: the box is alive (else R2
    judges) and nothing came on ``conn`` meanwhile (:func:`still_quiet`). The check's answer latency goes to
    ``paced`` (the box's own pace bounds the next short waits, :meth:`~.quiet.Hangs.cut_s`)."""
    if isinstance(alive, Answer):
        paced(alive.latency_s)
    return responsive(alive) and still_quiet(conn)

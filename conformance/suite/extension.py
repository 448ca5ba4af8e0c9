"""Does the box implement the extension E (actions 26/27)? Asked once, on one connection."""

from __future__ import annotations

from ..harness.client import Answer, Malformed, Silence, TcpConnection
from ..harness.liveness import PROBE_NONE
from ..protocol import Action, request


def detect_extension(conn: TcpConnection) -> tuple[bool, str]:
    """(implemented, how it was decided) from a result request (27) on ``conn``.

    A box without E may stay silent (A5): a NONE probe behind the request bounds the
    wait. Implemented means the box answers 27 at all, even wrongly (then the E cases
    judge it)."""
    conn.send(request(Action.VISION_RESULT), "detect extension E: result request (27)")
    conn.send(PROBE_NONE, "probe: NONE; its answer bounds the wait")
    outcome = conn.next_outcome()
    if isinstance(outcome, Answer) and outcome.frame.action == Action.NONE and outcome.frame.error_code == 0:
        outcome = Silence(outcome.latency_s)  # the probe answered first: 27 got none
    header = outcome.error.header if isinstance(outcome, Malformed) else None
    supported = (isinstance(outcome, Answer) and outcome.frame.action == Action.VISION_RESULT) or (
        header is not None and header.action == Action.VISION_RESULT and header.transfer_type == 0x10)
    how = ("detected (the box answered a result request)" if supported
           else f"not implemented (to a result request the box {outcome.describe()})")
    return supported, how

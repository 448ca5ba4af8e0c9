"""Does the box implement the extension E (actions 26/27)? Decided on positive evidence only.

E is *implemented* when an answer to a result request (27) or a ProgIdx (26) carries a
type-03 block (E1; well-formed or not, e.g. result code 404), or when 27 is answered
with action 27 and error 0000. Everything else a box may do to an action it does not
know (A5: silence, a non-zero error without a block, with the action echoed or 00, a
close) is a refusal: *not implemented*, and then A5-02 judges 26/27 as unknown actions.
A refusal of 27 alone is not the end: 26 is asked next (a box may implement 26 and
answer 27 wrongly; then it implements E, and the E cases judge it).

Each request is followed by a NONE probe on the same connection: answers come in order
(A1), so the probe's answer bounds the wait for a box that stays silent.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

from ..protocol import Action, BlockType, Frame, Header, Profile, TransferType, request, value_blocks
from .client import Answer, Closed, Malformed, Outcome, Silence, TcpConnection
from .liveness import PROBE_NONE
from .target import Target, Unreachable
from .transcript import Transcript

#: The program index sent when 27 gave no evidence either way.
PROG_IDX_VALUE = 7


@dataclass(frozen=True)
class Probe:
    """What one detection request got: its own answer (or silence, or a close)."""

    action: Action
    outcome: Outcome
    #: the box answered the NONE probe behind the request, not the request itself
    unanswered: bool = False

    @property
    def evidence(self) -> str:
        """Why this answer shows E is implemented ("" when it does not)."""
        header = _header(self.outcome)
        if self.unanswered or header is None or header.transfer_type != TransferType.BOX_TO_ROBOT:
            return ""
        if header.block_type == BlockType.VALUE:
            return "its answer carries a type-03 block"
        if self.action is Action.VISION_RESULT and header.action == self.action and header.error_code == 0:
            return "it is answered 0000 with the action echoed"
        return ""

    def describe(self) -> str:
        name = "result request (27)" if self.action is Action.VISION_RESULT else "ProgIdx (26)"
        return f"{name}: {self.seen()}"

    def seen(self) -> str:
        if self.unanswered:
            return "no answer (the NONE probe behind it was answered)"
        header = _header(self.outcome)
        if header is None:
            return f"the box {self.outcome.describe()}"
        blocks = "no block" if header.block_count == 0 else f"{header.block_count} block(s) of type {header.block_type:02X}"
        return (f"transfer type {header.transfer_type:02X}, action {header.action:02X}, error "
                f"0x{header.error_code:04X}, {blocks}")


def _header(outcome: Outcome) -> Header | None:
    if isinstance(outcome, Answer):
        return outcome.frame.header
    if isinstance(outcome, Malformed):
        return outcome.error.header
    return None


def _is_probe_answer(outcome: Outcome) -> bool:
    return isinstance(outcome, Answer) and outcome.frame.action == Action.NONE and outcome.frame.error_code == 0 \
        and not outcome.frame.blocks


def ask(conn: TcpConnection, frame: Frame, note: str, wait_s: float) -> Probe:
    """Send ``frame`` and a NONE probe; what the box did with ``frame`` within ``wait_s``."""
    action = Action(frame.action)
    if not conn.send(frame, note) or not conn.send(PROBE_NONE, "probe: NONE; its answer bounds the wait"):
        return Probe(action, conn.closed_by_peer or Closed(False, 0.0))
    start = time.monotonic()
    # an explicit wait: silence is a legal refusal here (A5), not a late answer (T1)
    outcome = conn.next_outcome(wait_s, since=start)
    if _is_probe_answer(outcome):
        return Probe(action, Silence(time.monotonic() - start, skipped=True), unanswered=True)
    return Probe(action, outcome)


def detect_extension(conn: TcpConnection) -> tuple[bool, str]:
    """(implemented, what the detection saw): :func:`detect_with_probes` without the probes."""
    implemented, how, _seen = detect_with_probes(conn)
    return implemented, how


def ask_result(conn: TcpConnection, note: str = "detect extension E: result request (27)") -> Probe:
    """A result request (27) and a NONE probe on ``conn``; E5: 27 is bounded by vision_time_out, not
    time_out (a box may take that long to have a result)."""
    return ask(conn, request(Action.VISION_RESULT), note, max(conn.time_out_s, conn.profile.vision_time_out_s))


def detect_with_probes(conn: TcpConnection) -> tuple[bool, str, list[Probe]]:
    """(implemented, what the detection saw, its probes: the result request's first) from a result
    request (27) on ``conn``, then, when 27 gave no positive evidence and the box is seen answering
    (or closing), a ProgIdx (26) on a fresh connection (``conn`` may be closed, or hold the probe's
    answer). A box that answered neither 27 nor the probe is not asked again (one wait, not two)."""
    seen = [ask_result(conn)]
    first = seen[0]
    quiet = isinstance(first.outcome, Silence) and not first.unanswered  # not even the probe was answered
    if not first.evidence and not quiet:
        other = TcpConnection(conn.transcript, conn.target, conn.profile, conn.label, conn.time_out_s)
        try:
            other.connect()
        except Unreachable:
            pass  # the box is gone: no more evidence to gather (the cases' liveness checks report it)
        else:
            prog_idx = request(Action.PROG_IDX, value_blocks([PROG_IDX_VALUE], conn.profile.first_index))
            seen.append(ask(other, prog_idx, f"detect extension E: ProgIdx (26) {PROG_IDX_VALUE}", other.time_out_s))
            other.close()
    return (*verdict(seen), seen)


def verdict(seen: list[Probe]) -> tuple[bool, str]:
    """(implemented, how it was decided) from the detection requests' outcomes."""
    proof = next((p for p in seen if p.evidence), None)
    observed = "; ".join(p.describe() for p in seen)
    if proof is not None:
        name = "27" if proof.action is Action.VISION_RESULT else "26"
        return True, f"implemented (detected: {name}: {proof.evidence}; {observed})"
    return False, (f"not implemented (detected: no answer to 26 or 27 carries a type-03 block and 27 is not answered "
                   f"0000, a refusal A5 allows; {observed})")


def extension_for(mode: str, target: Target, profile: Profile, transcript: Transcript) -> tuple[bool, str]:
    """``--extension on|off|auto``: forced, or detected on a fresh connection (not checked when unreachable)."""
    if mode != "auto":
        return mode == "on", "forced on" if mode == "on" else "off (--extension off)"
    conn = TcpConnection(transcript, target, profile, "extension detection")
    try:
        conn.connect()
    except Unreachable:
        return False, "not checked (the box could not be reached)"
    try:
        return detect_extension(conn)
    finally:
        conn.close()

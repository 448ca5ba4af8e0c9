"""Helpers of the golden-vector cases (conformance/cases/vector_replay.py): loading the vectors, applicability, what each may be answered."""

from __future__ import annotations

import socket
from typing import Any

import pytest

from ..evidence.vectors_file import REPO_VECTORS, Vector, load_dir
from ..harness.client import Answer, Outcome
from ..harness.transcript import Kind
from ..protocol import (
    ACTION_ERROR,
    HEADER_LEN,
    Action,
    ProtocolError,
    TransferType,
    Transport,
    codec_for,
    peek_header,
    request,
)
from ..protocol.answers import Cycle
from ..protocol.constants import CHECK_LEN
from .case_context import CaseContext
from .case_judge import Skip, answered, answered_allowed
from .lanes import ALONE_MARK, stateless_frame
from .record import Expect

VECTORS_DIR = REPO_VECTORS / "frames"


def load() -> tuple[list[Vector], str]:
    try:
        found = load_dir(VECTORS_DIR)
    except (OSError, ValueError, KeyError) as exc:
        return [], f"the golden vectors in {VECTORS_DIR} cannot be read: {exc}"
    mine = [v for v in found if v.transport is Transport.TCP and v.direction is TransferType.ROBOT_TO_BOX]
    return mine, "" if mine else f"no robot-to-box TCP golden vectors found in {VECTORS_DIR} (not packaged?)"


VECTORS, MISSING = load()


def params(result: str) -> list[Any]:
    """The vectors of one kind. A valid or acceptable one that may change the box's state (a CycleOn, a
    ProgIdx, two frames) runs alone; an invalid one is refused by a legal box, whatever its action."""
    chosen = [pytest.param(v, id=v.name, marks=() if result == "invalid" or stateless_frame(v.data)
                           else getattr(pytest.mark, ALONE_MARK)) for v in VECTORS if v.result == result]
    return chosen or [pytest.param(None, id="no-vectors")]


def has_blocks(v: Vector) -> bool:
    head = peek_header(v.data)
    return head is not None and head.block_count > 0


def applicable(isight: CaseContext, v: Vector | None) -> Vector:
    """The vector, or Skip with the reason it cannot be judged in this run."""
    if v is None:
        raise Skip(MISSING or "no golden vectors of this kind")
    isight.details["vector"] = {"file": v.file, "tcId": v.tc_id, "comment": v.comment, "clauses": list(v.clauses),
                                "flags": list(v.flags), "result": v.result, "hex": v.data.hex()}
    prof = isight.profile
    if prof.byte_order != "big" or prof.float_byte_order != "big":
        raise Skip(f"the vectors are big-endian (F4/B4); this run's profile has byte_order={prof.byte_order}, "
                   f"float_byte_order={prof.float_byte_order}")
    if v.profile.first_index != prof.first_index and has_blocks(v):
        raise Skip(f"vector written for first index {v.profile.first_index} (its group's profile); "
                   f"this run's profile uses --first-index {prof.first_index}")
    if "Extension" in v.flags and v.result != "invalid" and not isight.session.detect_extension(isight.transcript):
        raise Skip(f"extension vector and the box lacks E ({isight.session.extension_how}); A5-02 covers 26/27 then")
    return v


def run_profile_accepts(isight: CaseContext, v: Vector) -> bool:
    """Does the run's profile read these bytes as a valid request (e.g. a lenient profile)?"""
    try:
        codec_for(isight.profile).parse(v.data, Transport.TCP, TransferType.ROBOT_TO_BOX)
    except ProtocolError:
        return False
    return True


def announced_len(data: bytes) -> int:
    head = peek_header(data)
    return HEADER_LEN + CHECK_LEN if head is None else head.frame_length


def restore_idle(isight: CaseContext, outcome: Outcome, conn: Any) -> None:
    """A CycleOn the box took (0000) leaves the shared cycle on: switch it off again."""
    if isinstance(outcome, Answer) and outcome.frame.action == Action.CYCLE_ON and outcome.frame.error_code == 0:
        target = conn if conn is not None and conn.closed_by_peer is None else isight.connect("cleanup")
        target.request(request(Action.CYCLE_OFF), "cleanup: CycleOff, so the box is idle again (not judged)")


def prog_idx_expect(value: int, conflict: str) -> Expect:
    """E2: the same index, or 409: in the block, or (``--progidx-conflict error-code``) in the error field."""
    def ok(o: Outcome) -> bool:
        if not isinstance(o, Answer) or o.frame.action != Action.PROG_IDX or not o.frame.blocks:
            return False
        got, err = getattr(o.frame.blocks[0], "value", None), o.frame.error_code
        in_error = conflict == "error-code" and err in (409, 0x0409)  # as extension_e's CONFLICT_ERRORS
        return (got == value and err == 0) or (got == 409 and err in (0, 409)) or in_error

    where = "409 in the error field" if conflict == "error-code" else "409"
    return Expect(f"answered PROG_IDX carrying {value} with error 0000, or {where} (E2)", ok)


def valid_expect(v: Vector, action: Action, conflict: str = "block") -> Expect:
    if action is Action.CYCLE_ON:
        return answered_allowed(action, Cycle.IDLE)
    if action is Action.CYCLE_OFF:
        return answered_allowed(action, Cycle.ON)
    if action is Action.PROG_IDX:
        return prog_idx_expect(v.frame["blocks"][0]["value"] if v.frame else 0, conflict)
    if action is Action.VISION_RESULT:
        return answered(action)
    return answered_allowed(action)


def named_error(v: Vector) -> int | None:
    """A3: the error PROTOCOL.md names for this vector's parse error, if any."""
    head = peek_header(v.data)
    if head is None or not (head.start_ok and head.version_ok and head.is_request):
        return None
    if not v.clauses or v.clauses[0] not in ("B1", "B2", "B3", "B4", "B5"):
        return None
    try:
        return ACTION_ERROR.get(Action(head.action))
    except ValueError:
        return None


def send_cut_short(isight: CaseContext, data: bytes) -> Outcome:
    """A vector shorter than its header announces: send it, end the stream, see what follows."""
    isight.needs_liveness = True
    isight.last_sent = data
    conn = isight.connect("malformed")
    if not conn.send(data, "vector cut short: the header announces more bytes than follow"):
        return conn.closed_by_peer or conn.next_outcome(0)
    if conn.sock is not None:
        try:
            conn.sock.shutdown(socket.SHUT_WR)
            isight.transcript.add(conn.conn_id, Kind.CLOSE, note="end of stream after the vector (half-close)")
        except OSError:
            pass
    return conn.next_outcome()

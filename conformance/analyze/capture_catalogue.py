"""The cases ``analyze`` reports: one per (clause, side), ``OBS-<clause>-<side>``.

The side is who is judged, and who is at fault when the case does not pass: ``box``
(the server role, the clauses the active suite ``run`` tests) or ``robot`` (the client
role, the clauses ``certify-robot`` tests; their titles and requirements are taken from
its catalogue). A case's verdict is the worst of its findings; a case with nothing to
judge in the capture is SKIP.
"""

from __future__ import annotations

from ..model.verdicts import Level
from ..observed.robot_catalogue import (
    AWAIT_SPEC,
    CLOSE_SPEC,
    E4_SPEC,
    FRAME_SPECS,
    JITTER_SPEC,
    RATE_SPEC,
    S1_SPEC,
    spec,
)
from ..protocol.clauses import clause as registry_clause
from ..protocol.clauses import clause_ids, text_of
from ..suite.record import CaseRecord
from .findings import BOX, ROBOT

__all__ = ["SPECS", "case_id", "spec_for"]

MUST, SHOULD = Level.MUST, Level.SHOULD


def case_id(clause: str, side: str) -> str:
    return f"OBS-{clause}-{side}"


def _box(clause: str, title: str, requirement: str, expect: str, level: Level = MUST,
         clauses: tuple[str, ...] = ()) -> CaseRecord:
    return spec(case_id(clause, BOX), clauses or (clause,), level, title, requirement, expect)


def _robot(clause: str, box: CaseRecord, clauses: tuple[str, ...] | None = None, title: str = "") -> CaseRecord:
    return spec(case_id(clause, ROBOT), clauses or box.clauses, box.level, title or box.title, box.requirement,
                box.expect)


_BOX_SPECS = (
    _box("F1", "Answers start with FE FE", "F1: the start word is FE FE; nothing between frames",
         "every answer's first two bytes are fe fe"),
    _box("F2", "Answers carry version 00 01", "F2: the version field is 00 01", "bytes 2-3 of every answer are 00 01"),
    _box("F3", "Answers carry transfer type 10", "F3: transfer type 10 on every box→robot frame",
         "byte 4 of every answer is 10"),
    _box("F4", "Answers' multi-byte fields in the profile's byte order",
         "F4 [decision]: multi-byte fields are big-endian (the profile's byte order)",
         "no answer reads as absurd values that become plausible byte-swapped"),
    _box("F5", "An answer is exactly 12 + N×L + 2 bytes", "F5: a frame is exactly 12 + N×L + 2 bytes",
         "every answer's length matches its header"),
    _box("F6", "Over TCP the box sends check 00 00", "F6 [decision]: a TCP sender MUST send 00 00 in the check field",
         "the last two bytes of every TCP answer are 00 00"),
    _box("F7", "UDP answers: one frame per datagram with the CRC-16",
         "F7: over UDP one datagram is one frame and the check field is the profile's CRC-16",
         "every answer datagram is one frame with the right CRC"),
    _box("A1", "Every request answered exactly once, in order",
         "A1: the box answers every well-formed request with exactly one frame, in request order on that "
         "connection; S6: every pose on the stream is answered (pipelined)",
         "each request's answer follows in order; none missing (within the capture), none extra", clauses=("A1", "S6")),
    _box("A2", "Answers echo the action and carry no blocks",
         "A2: an answer has transfer type 10, echoes the request's action and carries no blocks (26/27: E2, E3)",
         "every answer echoes its request's action with the block layout A2 (or E2/E3) fixes"),
    _box("A3", "Error codes as A3 defines them",
         "A3: 0001 only for CycleOn, 0002 only for CycleOff, 1001 for a bad pose, 1002 for a bad tolerance; a "
         "malformed 23/24/25 SHOULD be answered with its action's error",
         "a well-formed request answered 0000 (CycleOff 0002 allowed); a malformed one with its action's error",
         clauses=("A3",)),
    _box("A4", "NONE is answered NONE with 0000", "A4: action 00 is answered with action 00 and error 0000",
         "every NONE request's answer is NONE 0000"),
    _box("B4", "NaN or infinity treated as a parse error",
         "B4 [decision]: NaN or infinity in a pose or tolerance SHOULD be treated as a parse error (answered "
         "1001/1002, never 0000)", "every request with a non-finite float the robot sent answered with an error",
         SHOULD),
    _box("R1", "Never 0000 to malformed input",
         "R1/A5: a frame that breaks F, B or A5 (a parse error or not a request) is never answered 0000",
         "silence, a non-zero error or a close after every malformed frame the robot sent", clauses=("R1", "A5")),
    _box("R6", "After garbage the box resynchronises or closes",
         "R6 [decision]: after garbage the box SHOULD resynchronise on the next valid header or close",
         "the valid requests after the robot's garbage are answered, or the connection is closed", SHOULD),
    _box("R7", "A bad datagram is never answered 0000, and is dropped",
         "R7: a datagram with a wrong CRC or not one frame long MUST NOT be answered 0000 and SHOULD be dropped",
         "no answer to a bad datagram (a non-zero error is NON-STRICT, 0000 is FAIL)"),
    _box("S2", "CycleOn answered 0000, or 0001 when not ready",
         "S2: CycleOn is answered 0000, or 0001 when the box is not ready (then the cycle is inconclusive); S3: "
         "CycleOn while a cycle is on MAY be answered anything",
         "every CycleOn the capture shows the box idle for answered 0000 or 0001 (0001 is reported; others, when "
         "the cycle state is not known, are INFORMATIONAL)"),
    _box("S3", "Poses answered 0000 whether or not a cycle is on",
         "S3 [decision]: poses (23) and register poses (24) are accepted and answered 0000 in any cycle state",
         "every well-formed pose answered 0000"),
    _box("S5", "After the robot closes, the box closes its side",
         "S5: after the robot closes a connection the box closes its side and frees it",
         "the box's FIN or RST follows the robot's FIN within time_out"),
    _box("T1", "Every answer within time_out (vision_time_out for 27)",
         "T1: every answer arrives within time_out of its request; E5: vision_time_out bounds the result request",
         "each request's answer within the bound, measured between the capture's time stamps", clauses=("T1", "E5")),
    _box("T2", "Stream poses answered without a growing backlog",
         "T2: at the stream rate every pose is answered and the answer latency does not grow over the run",
         "per stream, last-quarter p50 latency ≤ first-quarter p50 + max(20 ms, first-quarter p50)", clauses=("T2", "S6")),
    _box("E1", "Type-03 answer blocks: index + int32, L = 5", "E1: a type-03 block is index + int32 (L = 5)",
         "every 26/27 answer block is well-formed"),
    _box("E2", "ProgIdx answered with the same index or 409",
         "E2: the box answers ProgIdx with one type-03 block holding the index sent, or 409",
         "every ProgIdx answer holds the request's index or 409 (409 is reported)"),
    _box("E3", "Result request answered with a ResultCode",
         "E3: the result request is answered with one type-03 block: 1, 2, 10, 20, 202, 400 or 409",
         "every result answer holds a ResultCode the box may send (never 0 or 404)"),
)

_ROBOT_SPECS = (
    *(_robot(clause, spec) for clause, spec in FRAME_SPECS.items()),
    _robot("A1", AWAIT_SPEC),
    _robot("S1", S1_SPEC),
    _robot("E4", E4_SPEC),
    _robot("S5", CLOSE_SPEC),
    spec(case_id("T2", ROBOT), ("T2",), MUST, "Stream rate and send-interval jitter as declared",
         f"{RATE_SPEC.requirement}; {JITTER_SPEC.requirement}", f"{RATE_SPEC.expect}; {JITTER_SPEC.expect}"),
)

#: Every case, keyed by (clause, side), in report order: the box's, then the robot's.
SPECS: dict[tuple[str, str], CaseRecord] = {
    **{(s.id.split("-")[1], BOX): s for s in _BOX_SPECS},
    **{(s.id.split("-")[1], ROBOT): s for s in _ROBOT_SPECS},
}


def spec_for(clause: str, side: str) -> CaseRecord:
    """The spec of (clause, side); a clause without one (a codec error naming an unusual
    clause) gets one from the clause registry, so no finding is ever dropped."""
    found = SPECS.get((clause, side))
    if found is None:
        known = clause in clause_ids()
        level = registry_clause(clause).level if known else MUST
        # not checked against the registry: the clause may be one it lacks (never drop a finding)
        found = CaseRecord(case_id(clause, side), (clause,), level,
                           f"{registry_clause(clause).title if known else clause} ({side})",
                           f"the {side} satisfies {clause}",
                           requirement=f"{clause}: {text_of(clause) or 'as PROTOCOL.md states it'}")
    return found

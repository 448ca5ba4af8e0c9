"""The case catalogue of ``certify-robot``: PROTOCOL.md's clauses read from the client
side, each case with a stable ID (``RB-<clause>-NN``), its clauses, its level, and the
acceptable outcomes in words. The judgments are in :mod:`.checks`."""

from __future__ import annotations

from collections.abc import Callable

from ..model.verdicts import Level
from ..protocol import Action
from ..protocol.clauses import clause as registry_clause
from ..protocol.clauses import text_of
from ..suite.record import CaseRecord, record
from .robot_frames import FrameRecord

MUST, SHOULD, MAY = Level.MUST, Level.SHOULD, Level.MAY


def spec(id: str, clauses: tuple[str, ...], level: Level, title: str, requirement: str, expect: str) -> CaseRecord:
    """A check of the client role as the suite's one case record (:class:`~conformance.suite.record.CaseRecord`)."""
    return record(id, clauses, level, title, expect, requirement=requirement)


def _frame_spec(clause: str, title: str | None = None, requirement: str | None = None, level: Level = MUST) -> CaseRecord:
    """A frame case; the title and requirement are the clause's own (from the registry) unless
    the robot's side of it needs other words."""
    return spec(f"RB-{clause}-01", (clause,), level, title or registry_clause(clause).title,
                requirement or f"{clause}: {text_of(clause)}",
                f"every frame the robot sends satisfies {clause}" if level is MUST else
                f"every frame satisfies {clause} (a SHOULD: NON-STRICT otherwise)")


#: Frame cases, keyed by the clause a decoder error names (F4 is the heuristic's).
FRAME_SPECS: dict[str, CaseRecord] = {s.clauses[0]: s for s in (
    _frame_spec("F1", requirement="F1: the start word is FE FE; no bytes between frames"),
    _frame_spec("F2"),
    _frame_spec("F3", "Transfer type 01 on every robot→box frame"),
    spec("RB-F4-01", ("F4", "B4"), MUST, "Big-endian header fields and floats",
         "F4/B4 [decision]: multi-byte fields and float32/int32 values are big-endian (the profile's byte order)",
         "no frame reads as absurd values that become plausible byte-swapped"),
    _frame_spec("F5"),
    _frame_spec("F6", requirement="F6 [decision]: a TCP sender MUST send 00 00 in the check field"),
    _frame_spec("F7"),
    _frame_spec("A5", "Only request actions", "A5: the action is one PROTOCOL.md defines"),
    _frame_spec("B1"),
    _frame_spec("B2"),
    _frame_spec("B3", "Block indexes from the first index, rising by one"),
    _frame_spec("B4", "Finite floats (no NaN or infinity)", "B4 [decision]: NaN or infinity SHOULD not be sent", SHOULD),
    _frame_spec("B5"),
    _frame_spec("E1"),
    _frame_spec("E2", "ProgIdx request: one type-03 block", "E2: ProgIdx (26) carries the program index as one type-03 block"),
    _frame_spec("E3", "Result request: no blocks", "E3: the result request (27) carries no blocks"),
)}
FALLBACK = _frame_spec("F5")

_BLOCKS = {Action.POSE, Action.REGISTER_POSE, Action.TOLERANCE, Action.PROG_IDX}
_POSES = (Action.POSE, Action.REGISTER_POSE)
#: Which frames each frame case applies to, and what they are (none applies: SKIP).
APPLIES: dict[str, tuple[Callable[[FrameRecord], bool], str]] = {
    "F6": (lambda r: r.transport == "tcp", "frame over TCP"),
    "F7": (lambda r: r.transport == "udp", "UDP datagram"),
    "B1": (lambda r: r.action in _POSES, "pose frame (23/24)"),
    "B2": (lambda r: r.action == Action.TOLERANCE, "tolerance frame (25)"),
    "B3": (lambda r: r.action in _BLOCKS, "frame with blocks"),
    "B4": (lambda r: r.action in (*_POSES, Action.TOLERANCE), "frame with float values"),
    "B5": (lambda r: r.header_ok, "frame with a readable header"),
    "E1": (lambda r: r.action == Action.PROG_IDX, "ProgIdx frame (26)"),
    "E2": (lambda r: r.action == Action.PROG_IDX, "ProgIdx frame (26)"),
    "E3": (lambda r: r.action == Action.VISION_RESULT, "result request (27)"),
}
ANY_FRAME: tuple[Callable[[FrameRecord], bool], str] = (lambda r: True, "frame")

S1_SPEC = spec("RB-S1-01", ("S1",), MUST, "Canonical session order (S1), both connections",
               "S1: the milestones command connect → Send_Pos_On (stream connect) → CycleOn → CycleOff → "
               "Send_Pos_Off (stream closes) → command disconnect, in that order",
               "every milestone, in that order, each command once except CycleOn → CycleOff pairs, which may repeat "
               "(several parts primed in one session), each CycleOn closed by its CycleOff; NONE, poses (ISIGHT(3,35)), register poses "
               "(ISIGHT(3,36)) and tolerances may come in between on the command connection")
E4_SPEC = spec("RB-E4-01", ("E4", "S1"), MUST, "Canonical session order of the revision (E4), both connections",
               "E4: connect → ProgIdx → Send_Pos_On → CycleOn → trajectory → CycleOff → Send_Pos_Off → wait 1 s → "
               "result request → disconnect", "every milestone, in that order, each command once (27 may repeat after "
               "202; CycleOn → CycleOff pairs may repeat); NONE, poses, register poses and tolerances may come in between on the command connection")
AWAIT_SPEC = spec("RB-A1-01", ("A1", "T1"), MUST, "Each answer awaited on the command connection",
                  "A1/T1: the robot waits for each answer (up to time_out; vision_time_out for 27) before its next "
                  "request; the stream may pipeline (S6)",
                  "no request (or close) on a command connection before the previous answer or its time-out")
RATE_SPEC = spec("RB-T2-01", ("T2",), MUST, "Stream rate as declared",
                 "T2: the robot streams at its declared rate (--pose-rate)",
                 "mean rate and every ~1 s window within the rate tolerance of the declared rate")
JITTER_SPEC = spec("RB-T2-02", ("T2",), MUST, "Stream send-interval jitter",
                   "T2: measured as send-interval jitter at the declared rate",
                   "p99 |interval − 1/rate| within the jitter tolerance of the period")
CLOSE_SPEC = spec("RB-S5-01", ("S5",), MUST, "Both connections closed at the end",
                  "S5 (client side): the robot closes every connection it opened when its session ends",
                  "every connection closed by the robot (FIN or reset), none left for the suite to close")
INJECT_SPECS: dict[str, CaseRecord] = {
    "not-ready": spec("RB-INJECT-NOT-READY", ("S2",), MAY, "Reaction to CycleOn answered 0001 (injected)",
                      "S2: a box that is not ready answers CycleOn 0001", "any reaction (recorded)"),
    "slow": spec("RB-INJECT-SLOW", ("T1",), MAY, "Reaction to answers held back to 80 % of time_out (injected)",
                 "T1: every answer arrives within time_out", "any reaction (recorded; RB-A1-01 judges the waiting)"),
    "busy": spec("RB-INJECT-BUSY", ("E3",), MAY, "Reaction to a vision result 202 busy (injected)",
                 "E3: 202 means accepted but not finished", "any reaction (recorded)"),
    "close-mid-cycle": spec("RB-INJECT-CLOSE-MID-CYCLE", ("S1",), MAY,
                            "Reaction to the box closing the command connection after CycleOn (injected)",
                            "none: a box that closes mid-cycle breaks the session", "any reaction (recorded)"),
}
#: not a clause's case: the suite's own failures (no clause to check against the registry)
ERROR_SPEC = CaseRecord("RB-SUITE-01", (), MUST, "The suite's own failures", "no failure of the suite", requirement="none")



def catalogue(extension: bool = False) -> list[CaseRecord]:
    """Every case this command can report (for docs and ``--list``)."""
    return [*FRAME_SPECS.values(), E4_SPEC if extension else S1_SPEC, AWAIT_SPEC, RATE_SPEC, JITTER_SPEC, CLOSE_SPEC,
            *INJECT_SPECS.values()]
